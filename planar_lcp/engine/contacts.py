"""Stage 1 of a step: body poses -> world geometry -> contacts (gap, normal, point) for every candidate shape pair.

Numba only. Buffers are passed in; nothing is allocated.
"""

import math

import numpy as np
from numba import njit

from planar_lcp.engine.collision import contact_core_core, contact_core_halfplane
from planar_lcp.engine.constants import BODY_DYNAMIC, BODY_KINEMATIC, SHAPE_CORE, SHAPE_HALFPLANE


@njit(cache=True, _nrt=False)
def body_poses(m, q, qk, out):
    """World poses (nbody, 3) of all bodies: COM poses of dynamic ones from q, kinematic from qk, static fixed."""
    for b in range(m.body_kind.shape[0]):
        k = m.body_kind[b]
        if k == BODY_DYNAMIC:
            s = m.body_slot[b]
            out[b, 0] = q[s, 0]
            out[b, 1] = q[s, 1]
            out[b, 2] = q[s, 2]
        elif k == BODY_KINEMATIC:
            s = m.body_slot[b]
            out[b, 0] = qk[s, 0]
            out[b, 1] = qk[s, 1]
            out[b, 2] = qk[s, 2]
        else:
            out[b, 0] = m.static_pose[b, 0]
            out[b, 1] = m.static_pose[b, 1]
            out[b, 2] = m.static_pose[b, 2]


@njit(cache=True, _nrt=False)
def world_vertices(m, poses, out):
    """Core vertices of every shape in the world frame, (nvert, 2)."""
    for s in range(m.shape_body.shape[0]):
        if m.shape_kind[s] != SHAPE_CORE:
            continue
        b = m.shape_body[s]
        # math.cos, math.sin: the C library's in Python as compiled (np.cos can take a NumPy SIMD loop)
        c = math.cos(poses[b, 2])
        sn = math.sin(poses[b, 2])
        x = poses[b, 0]
        y = poses[b, 1]
        a0 = m.shape_vert_adr[s]
        for k in range(a0, a0 + m.shape_vert_num[s]):
            lx = m.vert_local[k, 0]
            ly = m.vert_local[k, 1]
            out[k, 0] = x + c * lx - sn * ly
            out[k, 1] = y + sn * lx + c * ly


@njit(cache=True, _nrt=False)
def _bounds(vw, a0, n):
    """(xmin, ymin, xmax, ymax) of the core vertices vw[a0:a0 + n]."""
    xmin = np.inf
    xmax = -np.inf
    ymin = np.inf
    ymax = -np.inf
    for k in range(a0, a0 + n):
        xmin = min(xmin, vw[k, 0])
        xmax = max(xmax, vw[k, 0])
        ymin = min(ymin, vw[k, 1])
        ymax = max(ymax, vw[k, 1])
    return xmin, ymin, xmax, ymax


@njit(cache=True, _nrt=False)
def _aabb_overlap(vw, a0, na, ra, b0, nb, rb, margin):
    axmin, aymin, axmax, aymax = _bounds(vw, a0, na)
    bxmin, bymin, bxmax, bymax = _bounds(vw, b0, nb)
    pad = ra + rb + margin
    return not (axmin > bxmax + pad or bxmin > axmax + pad or aymin > bymax + pad or bymin > aymax + pad)


@njit(cache=True, _nrt=False, inline='always')
def pair_contacts(m, vw, p, margin, forced, out_phi, out_n, out_p):
    """The contacts of shape pair p with gap < margin (any gap where forced) at the core vertices vw, into out_*
    (capacity 2): their gap, unit normal from shape B to shape A, and world point. Returns their number."""
    sa = m.pair_a[p]
    sb = m.pair_b[p]
    mg = np.inf if forced else margin
    a0 = m.shape_vert_adr[sa]
    na = m.shape_vert_num[sa]
    ra = m.shape_radius[sa]
    if m.shape_kind[sb] == SHAPE_HALFPLANE:
        return contact_core_halfplane(vw[a0:a0 + na], na, ra, m.hp_point_w[sb], m.hp_normal_w[sb], mg,
                                      out_phi, out_n, out_p)
    b0 = m.shape_vert_adr[sb]
    nb = m.shape_vert_num[sb]
    rb = m.shape_radius[sb]
    if not forced and not _aabb_overlap(vw, a0, na, ra, b0, nb, rb, margin):
        return 0
    return contact_core_core(vw[a0:a0 + na], na, ra, vw[b0:b0 + nb], nb, rb, mg, out_phi, out_n, out_p)


@njit(cache=True, _nrt=False)
def find_contacts(m, vw, margin, force_pair, con_pair, con_phi, con_n, con_p, tmp_phi, tmp_n, tmp_p):
    """All contacts with gap < margin (any gap for pairs with force_pair[p] true).

    Writes contact j's pair index, gap phi (m, negative = penetration), unit normal from shape B to shape A, and
    world point into the con_* buffers (capacity 2 per pair). Returns the number of contacts.
    """
    nc = 0
    for p in range(m.pair_a.shape[0]):
        cnt = pair_contacts(m, vw, p, margin, force_pair[p], tmp_phi, tmp_n, tmp_p)
        for k in range(cnt):
            con_pair[nc] = p
            con_phi[nc] = tmp_phi[k]
            con_n[nc, 0] = tmp_n[k, 0]
            con_n[nc, 1] = tmp_n[k, 1]
            con_p[nc, 0] = tmp_p[k, 0]
            con_p[nc, 1] = tmp_p[k, 1]
            nc += 1
    return nc


def contacts_at(arrays, q, qk, margin, all_pairs=False, m=None, python=False):
    """The contacts of one configuration, for Python callers outside a step (the compile step's start-overlap check,
    the pymunk comparison's gaps): allocates its buffers, unlike the kernels.

    arrays : the model's arrays (`ModelArrays`, engine/layout.py); q : (ndyn, 3) COM poses; qk : (nkin, 3) kinematic
    poses; margin : m, contacts with a gap below it; all_pairs : every shape pair's closest contacts at any gap;
    m : the kernels' struct over `arrays` (`model_struct(arrays)`), for a caller that examines many configurations
    (made here when None); python : run the kernels as Python on `arrays` (engine/interpreted.py: a cold cache's
    first run), the same answer. Returns (pair, phi, normal, point): (n,), (n,), (n, 2), (n, 2) arrays, one row per
    contact.
    """
    kernels = (body_poses, world_vertices, find_contacts)
    if python:
        from planar_lcp.engine.interpreted import python_version
        kernels, m = tuple(python_version(k) for k in kernels), arrays
    elif m is None:
        from planar_lcp.engine.layout import model_struct
        m = model_struct(arrays)  # the kernels' view: the step compiles for it, a namedtuple would compile them again
    body_poses_, world_vertices_, find_contacts_ = kernels
    npair = arrays.pair_a.shape[0]
    poses = np.zeros((arrays.body_kind.shape[0], 3))
    vw = np.zeros((max(1, arrays.vert_local.shape[0]), 2))
    body_poses_(m, np.ascontiguousarray(q, dtype=np.float64), np.ascontiguousarray(qk, dtype=np.float64), poses)
    world_vertices_(m, poses, vw)
    C = max(1, 2 * npair)
    pair, phi, normal, point = np.zeros(C, np.int64), np.zeros(C), np.zeros((C, 2)), np.zeros((C, 2))
    n = find_contacts_(m, vw, margin, np.full(max(1, npair), all_pairs, np.bool_), pair, phi, normal, point,
                      np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2)))
    return pair[:n], phi[:n], normal[:n], point[:n]
