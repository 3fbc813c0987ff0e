"""Admissibility: every grid point satisfies phi_j(q_k) >= -tol."""

import numpy as np
import pytest
from scenes import simulator


@pytest.mark.parametrize(
    "scene,setup",
    [
        ("star", {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.005, "n_impacts": 200}),
        ("billiard", {"q0": [0.2, 0.0], "v0": [0.3, 1.5], "h": 0.02, "n_impacts": 200}),
        ("star_nonlinear", {"q0": [0.0, 3.5, 0.0], "v0": [-2.0, 0.0, 5.0], "h": 0.01, "n_impacts": 100}),
    ],
)
def test_every_grid_point_admissible(scene, setup):
    sim = simulator(scene)
    res = sim.simulate(**setup)
    kern = sim.kernels.bind(sim.model.resolve_params(None))
    phis = np.array([kern.contacts(q)[0] for q in res.q])
    assert res.n_impacts == setup["n_impacts"]
    assert phis.min() >= -1e-9
    # Impact points lie on the contact.
    for im in res.impacts:
        assert abs(kern.contacts(im.q)[0][sim.system.contact_names.index(im.contact)]) < 1e-10
