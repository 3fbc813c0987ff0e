"""vcigen: variational collision integrators generated from a SymPy model.

Fetecau, Marsden, Ortiz, West, *Nonsmooth Lagrangian Mechanics and
Variational Collision Integrators*. The public API is shared/API.md.
"""

from .casadi_functions import casadi_functions, casadi_parameters
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
