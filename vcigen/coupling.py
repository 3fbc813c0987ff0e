"""Which cones share a body: the components of the nonzero pattern of a Delassus matrix.

Several cones near rest are aimed implicitly together (``FrictionModes._cone_brake``): the explicit aim made
a body's relative modes (the yaw of a rod on two cones) unstable. Cones on bodies that nothing couples (two
pucks) have no such modes, and one puck's aim must not depend on whether another, unrelated, is slow at the
same step; so only cones linked to another slow cone are braked together. The link is read off ``W = G M^-1
G^T`` over the cones' stick rows and the active rows: an entry that is exactly 0 (disjoint coordinates, a
block-diagonal mass) links nothing, any other does, and links carry through active rows (a rod's constraint).

Pure Python; ``templates/sustained_cone.c.j2`` has the same function (``coupled_cones``).
"""

from __future__ import annotations

import numpy as np


def coupled_cones(w: np.ndarray, n_cones: int) -> list[bool]:
    """For ``w = G M^-1 G^T``, ``G`` the two stick rows of each of ``n_cones`` cones (in order) then the
    active rows: whether each cone is linked to another cone through nonzero entries of ``w`` (union-find on
    its pattern, a cone's two rows one node)."""
    n = w.shape[0]
    root = list(range(n))

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = root[i]
        return i

    for c in range(n_cones):
        root[find(2 * c + 1)] = find(2 * c)
    for i in range(n):
        for j in range(i + 1, n):
            if w[i, j] != 0.0 or w[j, i] != 0.0:
                root[find(j)] = find(i)
    roots = [find(2 * c) for c in range(n_cones)]
    return [roots.count(r) > 1 for r in roots]
