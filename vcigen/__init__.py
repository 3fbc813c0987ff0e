"""vcigen: variational collision integrators generated from a SymPy model.

Fetecau, Marsden, Ortiz, West, *Nonsmooth Lagrangian Mechanics and
Variational Collision Integrators*. The public API is shared/API.md.
"""

from .derive import DiscreteSystem, derive
from .errors import CompileError, SolverError
from .impacts import ImpactTable
from .model import Model
from .result import Impact, Result
from .rules import MIDPOINT, RULES, TRAPEZOID, Rule, midpoint_rule
from .simulator import Simulator, build
from .stepper import Tolerances
from .sweep import sweep

__all__ = [
    "MIDPOINT",
    "RULES",
    "TRAPEZOID",
    "CompileError",
    "DiscreteSystem",
    "Impact",
    "ImpactTable",
    "Model",
    "Result",
    "Rule",
    "Simulator",
    "SolverError",
    "Tolerances",
    "build",
    "casadi_functions",
    "casadi_parameters",
    "derive",
    "midpoint_rule",
    "sweep",
]
__version__ = "0.1.0"


def __getattr__(name: str):
    """``casadi_functions`` and ``casadi_parameters``, imported when first asked for: they load the CasADi
    backend, which ``import vcigen`` does not (no backend module is loaded until one is built)."""
    if name in ("casadi_functions", "casadi_parameters"):
        from importlib import import_module

        mod = import_module(".casadi_functions", __name__)  # binds the submodule; replaced below
        globals().update(casadi_functions=mod.casadi_functions, casadi_parameters=mod.casadi_parameters)
        return globals()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
