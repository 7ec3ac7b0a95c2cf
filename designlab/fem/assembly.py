"""Vectorised assembly over (cells, quadrature points) straight into scipy.sparse matrices.

``cell_basis(mesh)`` evaluates shape-function gradients and ``det J * w`` once per mesh;
``stiffness(basis, lam, mu)`` forms every element matrix of isotropic elasticity with one batched
matmul and sums them into a CSR matrix through a cached node-block pattern (the sparsity
structure and the scatter map are computed once per mesh and reused). ``strain_operator(basis)``
is the sparse map u -> engineering strains at all quadrature points (its transpose maps
``dx * stress`` to internal forces). DOFs are interleaved: ``dof = 3 * node + component``.
Voigt order: (xx, yy, zz, xy, xz, yz) with engineering shear strains (Abaqus/CalculiX order).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from designlab.errors import ModelError
from designlab.fem.elements import Element, Quadrature, tet_element, tet_quadrature
from designlab.mesh.tetmesh import TetMesh

_CHUNK = 4096          # cells per batch: small temporaries stay in cache and are reused (first call
#                        with 32k-cell chunks paid ~3 s of page faults at 108k DOF)


@dataclass(frozen=True, eq=False)
class CellBasis:
    """Shape functions of ``mesh`` at the quadrature points of every cell.

    N: (nq, nn); dNdx: (m, nq, nn, 3) in 1/mm; dx: (m, nq) = det J * weight (mm^3);
    x: (m, nq, 3) quadrature point coordinates (mm)."""

    mesh: TetMesh
    element: Element
    quadrature: Quadrature
    N: np.ndarray
    dNdx: np.ndarray
    dx: np.ndarray
    x: np.ndarray

    @property
    def n_dofs(self) -> int:
        return 3 * self.mesh.n_points

    @property
    def n_qp(self) -> int:
        return self.dx.size


def cell_basis(mesh: TetMesh, degree: int | None = None) -> CellBasis:
    """Gradients and integration weights at the quadrature points (default rule of the
    element: 1 point for TET4, 4 points for TET10). Raises ModelError on inverted cells."""
    el = tet_element(mesh.cells.shape[1])
    q = el.quadrature if degree is None else tet_quadrature(degree)
    X = mesh.points[mesh.cells]                          # (m, nn, 3)
    dN = el.dN(q.points)                                 # (nq, nn, 3)
    J = np.einsum("eai,qaj->eqij", X, dN, optimize=True)  # (m, nq, 3, 3) dx_i/dxi_j
    det = np.linalg.det(J)
    scale = np.abs(det).max() if det.size else 1.0
    bad = ~(det > 1e-12 * scale)
    if bad.any():
        cells = np.nonzero(bad.any(axis=1))[0]
        raise ModelError(f"{len(cells)} inverted or degenerate elements (non-positive Jacobian), "
                         f"first element id {cells[0]}")
    invJ = np.linalg.inv(J)
    dNdx = np.einsum("qaj,eqji->eqai", dN, invJ, optimize=True)
    N = el.N(q.points)
    x = np.einsum("qa,eai->eqi", N, X)
    return CellBasis(mesh, el, q, N, dNdx, det * q.weights, x)


# --- sparsity pattern (node blocks), cached per mesh ---

@dataclass(frozen=True)
class BlockPattern:
    """CSR pattern of the node graph and the scatter map of element node pairs into it."""

    indptr: np.ndarray
    indices: np.ndarray
    scatter: np.ndarray        # (m, nn, nn) -> block position
    n_nodes: int


_PATTERNS: "weakref.WeakKeyDictionary[TetMesh, BlockPattern]" = weakref.WeakKeyDictionary()


def block_pattern(mesh: TetMesh) -> BlockPattern:
    """Node-block sparsity of ``mesh`` (computed once per mesh object and cached)."""
    pat = _PATTERNS.get(mesh)
    if pat is None:
        c = mesh.cells.astype(np.int64)
        m, nn = c.shape
        n = mesh.n_points
        key = (c[:, :, None] * n + c[:, None, :]).ravel()
        uniq, inv = np.unique(key, return_inverse=True)
        rows = uniq // n
        indptr = np.zeros(n + 1, np.int64)
        np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
        pat = BlockPattern(indptr, (uniq % n).astype(np.int64), inv.reshape(m, nn, nn), n)
        _PATTERNS[mesh] = pat
    return pat


def _bsr_to_csr(pat: BlockPattern, blocks: np.ndarray) -> sp.csr_matrix:
    n = 3 * pat.n_nodes
    K = sp.bsr_matrix((blocks.reshape(-1, 3, 3), pat.indices, pat.indptr), shape=(n, n))
    return K.tocsr()


def stiffness(basis: CellBasis, lam, mu) -> sp.csr_matrix:
    """Isotropic elastic stiffness (N/mm) for Lame parameters ``lam``, ``mu`` (MPa): scalars
    or (m,) per cell. Symmetric CSR of size 3 n_points.

    With A_ij[e, a, b] = sum_q w G[e,q,a,i] G[e,q,b,j] (six batched matmuls, i <= j), the
    (i, j) block is K_ij = lam A_ij + mu A_ji + mu delta_ij (A_00 + A_11 + A_22), and
    A_ji = A_ij^T (a <-> b): every block is scattered by ``bincount`` into the cached pattern."""
    mesh = basis.mesh
    pat = block_pattern(mesh)
    m, nq, nn, _ = basis.dNdx.shape
    lam = np.broadcast_to(np.asarray(lam, float), (m,))
    mu = np.broadcast_to(np.asarray(mu, float), (m,))
    nnzb = len(pat.indices)
    data = np.zeros((9, nnzb))
    for s in range(0, m, _CHUNK):
        e = slice(s, min(s + _CHUNK, m))
        G = np.ascontiguousarray(basis.dNdx[e].transpose(3, 0, 2, 1))     # (3, c, nn, nq)
        Gw = G * basis.dx[e][None, :, None, :]
        A = {(i, j): np.matmul(Gw[i], G[j].transpose(0, 2, 1))
             for i in range(3) for j in range(i, 3)}
        la, mu_ = lam[e, None, None], mu[e, None, None]
        tr = mu_ * (A[0, 0] + A[1, 1] + A[2, 2])
        idx = pat.scatter[e].ravel()
        idxT = pat.scatter[e].transpose(0, 2, 1).ravel()
        for (i, j), a in A.items():
            if i == j:
                blk = (la + mu_) * a + tr
                data[4 * i] += np.bincount(idx, weights=blk.ravel(), minlength=nnzb)
            else:
                blk = la * a + mu_ * a.transpose(0, 2, 1)                     # K_ij
                w = blk.ravel()
                data[3 * i + j] += np.bincount(idx, weights=w, minlength=nnzb)
                data[3 * j + i] += np.bincount(idxT, weights=w, minlength=nnzb)   # K_ji = K_ij^T
    return _bsr_to_csr(pat, np.ascontiguousarray(data.T))


def mass(basis: CellBasis, density) -> sp.csr_matrix:
    """Consistent mass matrix (t), ``density`` in t/mm^3 (scalar or (m,)). Use a basis built
    with ``degree=2`` (TET4) or ``degree=4`` (TET10) for exact integration."""
    mesh = basis.mesh
    pat = block_pattern(mesh)
    rho = np.broadcast_to(np.asarray(density, float), (mesh.n_cells,))
    M = np.einsum("qa,qb,eq,e->eab", basis.N, basis.N, basis.dx, rho, optimize=True)
    blocks = np.zeros((len(pat.indices), 9))
    for i in range(3):
        blocks[:, 4 * i] = np.bincount(pat.scatter.ravel(), weights=M.ravel(),
                                       minlength=len(pat.indices))
    return _bsr_to_csr(pat, blocks)


def strain_operator(basis: CellBasis) -> sp.csr_matrix:
    """Sparse (m * nq * 6, 3 n) map from nodal displacements to engineering strains
    (xx, yy, zz, xy, xz, yz) at every quadrature point, row = 6 * (e * nq + q) + component."""
    m, nq, nn, _ = basis.dNdx.shape
    G = basis.dNdx                                            # (m, nq, nn, 3)
    cells = basis.mesh.cells
    dof = 3 * cells[:, None, :, None] + np.arange(3)          # (m, 1, nn, 3)
    dof = np.broadcast_to(dof, (m, nq, nn, 3))
    qp = np.arange(m * nq).reshape(m, nq)[:, :, None]
    # (component, derivative index, displacement component)
    terms = [(0, 0, 0), (1, 1, 1), (2, 2, 2), (3, 1, 0), (3, 0, 1),
             (4, 2, 0), (4, 0, 2), (5, 2, 1), (5, 1, 2)]
    rows, cols, vals = [], [], []
    for comp, d, u in terms:
        rows.append(np.broadcast_to(6 * qp + comp, (m, nq, nn)).ravel())
        cols.append(dof[..., u].ravel())
        vals.append(G[..., d].ravel())
    B = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(6 * m * nq, 3 * basis.mesh.n_points))
    return B


def body_load(basis: CellBasis, b, cells: np.ndarray | None = None) -> np.ndarray:
    """Consistent nodal forces (3 n,) of a body force density ``b`` (N/mm^3): a (3,) vector,
    an (m, 3) per-cell array, or a callable ``b(x) -> (..., 3)`` of quadrature point
    coordinates; optionally only over the cells selected by the boolean/int array ``cells``."""
    x = basis.x
    if callable(b):
        bq = b(x)
    else:
        b = np.asarray(b, float)
        bq = np.broadcast_to(b[:, None, :] if b.shape == (len(x), 3) else b, x.shape)
    w = basis.dx
    sel = np.arange(basis.mesh.n_cells) if cells is None else np.asarray(cells)
    if sel.dtype == bool:
        sel = np.nonzero(sel)[0]
    fe = np.einsum("qa,eq,eqi->eai", basis.N, w[sel], bq[sel])          # (k, nn, 3)
    dofs = 3 * basis.mesh.cells[sel][:, :, None] + np.arange(3)
    return np.bincount(dofs.ravel(), weights=fe.ravel(), minlength=basis.n_dofs)
