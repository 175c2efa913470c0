"""Forward-mode dual numbers: a value and its derivatives along K input directions, for running the step's own code.

A `Dual` carries a float value `v` and a (K,) array `d` of its partial derivatives. Arithmetic computes the value
with exactly the floating-point operation the engine's code performs on floats (so a step run on duals has the
compiled step's values bit for bit: engine/interpreted.py) and the derivatives by the chain rule. Comparisons,
`min`, `max`, `abs` and `int` look at the value only: every branch of the code is taken as the float run takes it,
and the derivatives are those of the branch taken.

`NP` and `MATH` stand in for the `numpy` and `math` modules in the engine's functions run on duals: the few
elementary functions the kernels call (math.cos, math.sin, math.asinh, math.log2, np.hypot, np.sqrt, np.isfinite,
np.round) take duals, everything else is numpy's or math's own.
"""

import math
import types

import numpy as np


class Dual:
    """A value v (float) and its derivatives d ((K,) float array) along the K seeded directions."""

    __slots__ = ("v", "d")
    # numpy scalars defer to the reflected operators below instead of making a 0-d object array
    __array_ufunc__ = None

    def __init__(self, v, d):
        self.v = v
        self.d = d

    def __repr__(self):
        return f"Dual({self.v!r}, {self.d!r})"

    # arithmetic: the value by the float operation itself, the derivative by the chain rule
    def __add__(self, o):
        if isinstance(o, Dual):
            return Dual(self.v + o.v, self.d + o.d)
        return Dual(self.v + o, self.d)

    __radd__ = __add__

    def __sub__(self, o):
        if isinstance(o, Dual):
            return Dual(self.v - o.v, self.d - o.d)
        return Dual(self.v - o, self.d)

    def __rsub__(self, o):
        return Dual(o - self.v, -self.d)

    def __mul__(self, o):
        if isinstance(o, Dual):
            return Dual(self.v * o.v, self.d * o.v + o.d * self.v)
        return Dual(self.v * o, self.d * o)

    __rmul__ = __mul__

    def __truediv__(self, o):
        if isinstance(o, Dual):
            q = self.v / o.v
            return Dual(q, (self.d - o.d * q) / o.v)
        return Dual(self.v / o, self.d / o)

    def __rtruediv__(self, o):
        q = o / self.v
        return Dual(q, self.d * (-q / self.v))

    def __pow__(self, p):
        if isinstance(p, Dual):
            raise TypeError("Dual ** Dual is not used by the engine")
        val = self.v ** p
        return Dual(val, self.d * (p * self.v ** (p - 1)) if p != 0 else self.d * 0.0)

    def __neg__(self):
        return Dual(-self.v, -self.d)

    def __pos__(self):
        return self

    def __abs__(self):
        if tied(self.v, 0.0):
            # the kink of |x|: along the seeded direction |x| grows at |dx| on either side (one-sided derivative)
            return Dual(abs(self.v), np.abs(self.d))
        return -self if self.v < 0.0 else self

    # the value decides every branch
    def __lt__(self, o):
        return self.v < _val(o)

    def __le__(self, o):
        return self.v <= _val(o)

    def __gt__(self, o):
        return self.v > _val(o)

    def __ge__(self, o):
        return self.v >= _val(o)

    def __eq__(self, o):
        return self.v == _val(o)

    def __ne__(self, o):
        return self.v != _val(o)

    __hash__ = None

    def __bool__(self):
        return self.v != 0.0

    def __int__(self):
        # int() truncates: piecewise constant, derivative zero (the limit surface's table index)
        return int(self.v)

    # no __float__: writing a dual into a float64 array must fail, not drop its derivatives


def _val(x):
    return x.v if isinstance(x, Dual) else x


#: two values closer than this, relative to max(1, |a|, |b|), are a tie of max, min and abs: the collision module's
#: tolerance (engine/collision.py), far above round-off and far below any physical length or speed
TIE_RTOL = 1e-10


def tied(a, b):
    return abs(a - b) <= TIE_RTOL * max(1.0, abs(a), abs(b))


def dual_max(*args):
    """max() of duals and numbers: the value as max() takes it; at a tie between operands with different derivatives,
    the elementwise largest derivative, which is the one-sided derivative of max along each seeded direction."""
    return _fold(args, True)


def dual_min(*args):
    """min() as `dual_max` is max()."""
    return _fold(args, False)


def _fold(args, largest):
    if len(args) == 1:
        args = tuple(args[0])
    best = args[0]
    for a in args[1:]:
        best = _pick(best, a, largest)
    return best


def _pick(a, b, largest):
    if not isinstance(a, Dual) and not isinstance(b, Dual):
        return max(a, b) if largest else min(a, b)
    av, bv = _val(a), _val(b)
    win = (b if bv > av else a) if largest else (b if bv < av else a)
    if tied(av, bv):
        k = (a if isinstance(a, Dual) else b).d.shape[0]
        ad = a.d if isinstance(a, Dual) else np.zeros(k)
        bd = b.d if isinstance(b, Dual) else np.zeros(k)
        if not np.array_equal(ad, bd):
            d = np.maximum(ad, bd) if largest else np.minimum(ad, bd)
            record_tie()
            return Dual(_val(win), d)
    return win


#: called at every tie with different derivatives (forward.py counts them for the step's report)
_tie_listeners = []


def record_tie():
    import sys
    where = sys._getframe(3).f_code.co_name
    for f in _tie_listeners:
        f(where)


def value(x):
    """The float value of a dual or a number."""
    return x.v if isinstance(x, Dual) else float(x)


def values(a):
    """A float64 array of the values of an object array of duals and numbers."""
    a = np.asarray(a, dtype=object)
    return np.array([value(x) for x in a.ravel()], dtype=np.float64).reshape(a.shape)


def grads(a, k):
    """The derivatives (a.shape + (k,)) of an object array of duals and numbers."""
    a = np.asarray(a, dtype=object)
    out = np.zeros((a.size, k))
    for i, x in enumerate(a.ravel()):
        if isinstance(x, Dual):
            out[i] = x.d
    return out.reshape(a.shape + (k,))


def with_derivatives(a, da):
    """An object array of duals with values a (float array) and derivatives da (a.shape + (k,)); entries whose
    derivatives are all zero stay floats."""
    a = np.asarray(a, dtype=np.float64)
    out = np.empty(a.shape, dtype=object)
    flat, dflat = out.reshape(-1), da.reshape(a.size, da.shape[-1])
    for i, x in enumerate(a.ravel()):
        flat[i] = Dual(float(x), dflat[i].copy()) if np.any(dflat[i]) else float(x)
    return out


# --- the elementary functions the kernels call ------------------------------------------------------------------

def _sqrt(x):
    if not isinstance(x, Dual):
        return np.sqrt(x)
    r = np.sqrt(x.v)
    # at 0 the derivative is unbounded; the kernels test the root against 0 before dividing by it
    return Dual(r, x.d * (0.5 / r) if r > 0.0 else x.d * 0.0)


def _hypot(x, y):
    if not isinstance(x, Dual) and not isinstance(y, Dual):
        return np.hypot(x, y)
    xv, yv = _val(x), _val(y)
    r = np.hypot(xv, yv)
    if not r > 0.0:
        return Dual(r, _d(x, y) * 0.0)
    d = 0.0
    if isinstance(x, Dual):
        d = x.d * (xv / r)
    if isinstance(y, Dual):
        d = d + y.d * (yv / r)
    return Dual(r, d)


def _d(x, y):
    return x.d if isinstance(x, Dual) else y.d


def _isfinite(x):
    # the value's test, as the compiled step branches on it: derivatives that overflow are the caller's to report
    # ("unbounded"), not a step that failed
    if isinstance(x, Dual):
        return bool(np.isfinite(x.v))
    return np.isfinite(x)


def _round(x):
    # rounding is piecewise constant: the equilibration's powers of two carry no derivative
    return np.round(_val(x))


def _cos(x):
    if not isinstance(x, Dual):
        return math.cos(x)
    return Dual(math.cos(x.v), x.d * -math.sin(x.v))


def _sin(x):
    if not isinstance(x, Dual):
        return math.sin(x)
    return Dual(math.sin(x.v), x.d * math.cos(x.v))


def _asinh(x):
    if not isinstance(x, Dual):
        return math.asinh(x)
    return Dual(math.asinh(x.v), x.d / math.sqrt(1.0 + x.v * x.v))


def _log2(x):
    if not isinstance(x, Dual):
        return math.log2(x)
    return Dual(math.log2(x.v), x.d / (x.v * math.log(2.0)))


def _float64(x=0.0):
    return x if isinstance(x, Dual) else np.float64(x)


class _Namespace(types.SimpleNamespace):
    """A module's stand-in: the names set here, everything else from the module itself."""

    def __init__(self, module, **names):
        super().__init__(**names)
        self._module = module

    def __getattr__(self, name):
        return getattr(self._module, name)


#: `numpy` for the engine's code run on duals
NP = _Namespace(np, sqrt=_sqrt, hypot=_hypot, isfinite=_isfinite, round=_round, float64=_float64)
#: `math` for the engine's code run on duals
MATH = _Namespace(math, cos=_cos, sin=_sin, asinh=_asinh, log2=_log2, sqrt=_sqrt)
