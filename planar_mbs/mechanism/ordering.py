"""Fill-reducing order of the constraint rows, chosen once from the body-joint graph.

The multipliers come from ``S = Cq M^-1 Cq^T`` factored by an envelope (profile)
Cholesky (`planar_mbs.kernel.dynamics`): its cost is the sum of the squared row
profiles, so it depends on the order of the rows.  Two elements (ideal joints
and drivers, ordered together) couple in ``S`` when they share a body; ground
couples nothing.  Reverse Cuthill-McKee (Cuthill and McKee, "Reducing the
bandwidth of sparse symmetric matrices", 1969; George and Liu, "Computer
Solution of Large Sparse Positive Definite Systems", 1981) on this element graph
gives a small profile: a chain or a chain of closed loops gets a band of a few
rows, so one factorisation costs O(N), whatever order the model text lists the
joints in.  The rows of one element stay together (``joint_row`` / ``driver_row``
are the first rows of each element).
"""
from __future__ import annotations

import numpy as np

from .model import JOINT_ROWS, KernelModel


def reverse_cuthill_mckee(adj: list[list[int]]) -> list[int]:
    """Reverse Cuthill-McKee order of a graph given as neighbour lists: breadth-first
    from a node of least degree in each connected component, neighbours by increasing
    degree, then reversed (George and Liu).  Plain Python: compiling a model loads no
    scipy; O(E log E)."""
    deg = [len(a) for a in adj]
    seen = [False] * len(adj)
    order: list[int] = []
    for start in sorted(range(len(adj)), key=lambda i: (deg[i], i)):
        if seen[start]:
            continue
        seen[start] = True
        queue = [start]
        head = 0
        while head < len(queue):
            v = queue[head]
            head += 1
            for w in sorted(adj[v], key=lambda i: (deg[i], i)):
                if not seen[w]:
                    seen[w] = True
                    queue.append(w)
        order += queue
    return order[::-1]


def element_order(joint_body: np.ndarray, driver_body: np.ndarray) -> np.ndarray:
    """Permutation of the elements (joints 0..nj-1, then drivers) by reverse
    Cuthill-McKee on the graph "two elements share a body".

    Elements are first sorted by their bodies, so the result does not depend on
    the order the model text lists them in (only on the bodies' numbering)."""
    bodies = np.concatenate([np.asarray(joint_body, np.int64).reshape(-1, 2),
                             np.asarray(driver_body, np.int64).reshape(-1, 2)])
    ne = len(bodies)
    if ne <= 2:
        return np.arange(ne, dtype=np.int64)
    lo, hi = np.sort(bodies, axis=1).T
    canon = np.lexsort((np.arange(ne), hi, lo))  # text order only breaks exact ties
    b = bodies[canon]
    by_body: dict[int, list[int]] = {}
    for e in range(ne):
        for body in set(int(x) for x in b[e] if x >= 0):
            by_body.setdefault(body, []).append(e)
    adj: list[set[int]] = [set() for _ in range(ne)]
    for elems in by_body.values():
        for e in elems:
            adj[e].update(elems)
    for e in range(ne):
        adj[e].discard(e)
    perm = np.array(reverse_cuthill_mckee([sorted(a) for a in adj]), dtype=np.int64)
    return canon[perm].astype(np.int64)


def row_order(joint_type: np.ndarray, joint_body: np.ndarray,
              driver_body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(joint_row, driver_row): the first constraint row of every joint and driver
    with the elements placed in `element_order`."""
    jt = np.asarray(joint_type, np.int64)
    nj = len(jt)
    size = np.concatenate([JOINT_ROWS[jt], np.ones(len(driver_body), np.int64)]).astype(np.int64)
    order = element_order(joint_body, driver_body)
    start = np.zeros(len(size), np.int64)
    start[order] = np.concatenate([[0], np.cumsum(size[order])[:-1]]) if len(size) else []
    return start[:nj].copy(), start[nj:].copy()


def reorder(km: KernelModel) -> KernelModel:
    """The same model with its constraint rows in the fill-reducing order."""
    jb, db = np.asarray(km.joint_body, np.int64), np.asarray(km.driver_body, np.int64)
    bb = np.asarray(km.body_beam, np.int64)
    if bb.size:  # a beam's node bodies couple through its mass: one node of the graph per beam
        g = np.where(bb >= 0, len(bb) + bb, np.arange(len(bb)))
        jb, db = (np.where(x >= 0, g[np.maximum(x, 0)], -1) for x in (jb, db))
    jrow, drow = row_order(km.joint_type, jb, db)
    return km._replace(joint_row=jrow, driver_row=drow)
