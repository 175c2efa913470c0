"""Stage 2 of a step: group dynamic bodies into islands (connected by contacts between dynamic bodies).

Each island with at least one contact or support point is a separate LCP; a body that touches nothing (and has no
table friction) is integrated without one.
"""

import numpy as np
from numba import njit

from planar_lcp.engine.constants import BODY_DYNAMIC, BODY_KINEMATIC


@njit(cache=True, _nrt=False)
def _find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, inline='always')
def _union(parent, a, b):
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra != rb:
        # the smaller root wins: island numbering does not depend on contact order
        if ra < rb:
            parent[rb] = ra
        else:
            parent[ra] = rb


@njit(cache=True, _nrt=False)
def find_islands(m, ncon, con_pair, parent, island, servo_root):
    """island[d] = island id (0..K-1) of dynamic slot d. Returns K. Bodies joined by a contact share an island, and
    so do the bodies a force-limited kinematic body touches (its lag velocity is one for all of them);
    servo_root (nkin,) is work space."""
    ndyn = parent.shape[0]
    for d in range(ndyn):
        parent[d] = d
    for k in range(servo_root.shape[0]):
        servo_root[k] = -1
    for j in range(ncon):
        p = con_pair[j]
        ba = m.shape_body[m.pair_a[p]]
        bb = m.shape_body[m.pair_b[p]]
        if m.body_kind[ba] == BODY_DYNAMIC and m.body_kind[bb] == BODY_DYNAMIC:
            _union(parent, m.body_slot[ba], m.body_slot[bb])
        elif m.body_kind[bb] == BODY_KINEMATIC and m.kin_max_force[m.body_slot[bb]] > 0.0:
            k = m.body_slot[bb]
            if servo_root[k] < 0:
                servo_root[k] = m.body_slot[ba]
            else:
                _union(parent, m.body_slot[ba], servo_root[k])
    k = 0
    for d in range(ndyn):
        island[d] = -1
    for d in range(ndyn):
        r = _find(parent, d)
        if island[r] < 0:
            island[r] = k
            k += 1
        island[d] = island[r]
    return k


@njit(cache=True, _nrt=False)
def contact_island(m, island, con_pair, j):
    """Island of contact j. Relies on the invariant compile_scene establishes: side A of every pair is dynamic."""
    return island[m.body_slot[m.shape_body[m.pair_a[con_pair[j]]]]]


@njit(cache=True, inline='always')
def island_members(m, w, isl, ncon):
    """Fill w.island_con / w.island_sup with the contacts (of the ncon in w.con_*) and the support points of island
    isl, in increasing index order; returns their counts (nci, nsi)."""
    # np.int64 counters: a literal 0 would have numba compile every island solver once more for Literal[int](0),
    # while it infers the loop's type (measured: 129 compilations of a cold falling_rod before, 98 after)
    nci = np.int64(0)
    for j in range(ncon):
        if contact_island(m, w.body_island, w.con_pair, j) == isl:
            w.island_con[nci] = j
            nci += 1
    nsi = np.int64(0)
    for s in range(m.sup_dyn.shape[0]):
        if w.body_island[m.sup_dyn[s]] == isl:
            w.island_sup[nsi] = s
            nsi += 1
    return nci, nsi
