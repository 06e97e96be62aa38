#!/usr/bin/env python3
"""Re-solves a `palpa fe solve --out FILE.vtu` problem with scikit-fem, independently.

The VTU carries everything needed: the mesh (P1 `tetra` or P2 `tetra10`, VTK order),
point data `fixed` (supports), `nodal_force` (the assembled consistent load, N) and
`displacement` (palpa's answer, mm), and field data `young_kpa`, `poisson`,
`element_order`. This script rebuilds the same discrete problem in scikit-fem
(straight-sided Lagrange P1/P2 on the same tetrahedra), solves it, and prints the
largest difference from palpa's displacement, absolute and relative to max |u|.

    pip install scikit-fem meshio
    python3 scripts/xcheck/resolve_skfem.py u.vtu
Exit status 1 if the relative difference exceeds 1e-8 (solver precision at the
condition numbers of nearly incompressible tissue).
"""
import sys

import meshio
import numpy as np
from skfem import Basis, ElementTetP1, ElementTetP2, ElementVector, MeshTet, asm, condense, solve
from skfem.models.elasticity import lame_parameters, linear_elasticity


def main(path):
    m = meshio.read(path)
    order = int(round(float(np.ravel(m.field_data["element_order"])[0])))
    young = float(np.ravel(m.field_data["young_kpa"])[0]) * 1e-3  # kPa -> N/mm^2
    nu = float(np.ravel(m.field_data["poisson"])[0])
    cells = m.cells_dict["tetra10" if order == 2 else "tetra"]
    corners = cells[:, :4]
    nv = int(corners.max()) + 1
    mesh = MeshTet(m.points[:nv].T.copy(), corners.T.copy())
    elem = ElementVector(ElementTetP2() if order == 2 else ElementTetP1())
    basis = Basis(mesh, elem)
    K = asm(linear_elasticity(*lame_parameters(young, nu)), basis)

    # palpa node -> scikit-fem dofs (x, y, z).
    node_dofs = np.full((len(m.points), 3), -1, dtype=np.int64)
    node_dofs[:nv] = basis.nodal_dofs.T
    if order == 2:
        edge_index = {tuple(sorted(e)): i for i, e in enumerate(mesh.edges.T.tolist())}
        vtk_edges = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]
        for cell in cells:
            for k, (a, b) in enumerate(vtk_edges):
                e = edge_index[tuple(sorted((int(cell[a]), int(cell[b]))))]
                node_dofs[cell[4 + k]] = basis.edge_dofs[:, e]
    assert (node_dofs >= 0).all(), "every palpa node maps to scikit-fem dofs"

    f = np.zeros(basis.N)
    f[node_dofs.ravel()] = m.point_data["nodal_force"].ravel()
    fixed = m.point_data["fixed"].ravel() > 0.5
    D = node_dofs[fixed].ravel()
    u = solve(*condense(K, f, D=D))

    ours = m.point_data["displacement"]
    theirs = u[node_dofs]
    diff = np.abs(ours - theirs).max()
    scale = np.linalg.norm(ours, axis=1).max()
    print(f"nodes {len(m.points)}, dofs {basis.N}, fixed nodes {fixed.sum()}, P{order}, "
          f"E = {young * 1e3:g} kPa, nu = {nu:g}")
    print(f"max |u| = {scale:.6e} mm, max |u_palpa - u_skfem| = {diff:.3e} mm, relative {diff / scale:.3e}")
    return 0 if diff <= 1e-8 * scale else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
