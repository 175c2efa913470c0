"""What the environments check of their inputs before anything changes: actions and reset()'s options, each
refused with a ValueError that names the environment, the input, what it must be and what it was."""

import numpy as np


def shown(value, limit=120):
    """A value for a message: its numbers as a list when it has some, else its repr; at most `limit` characters."""
    try:
        text = repr(value) if isinstance(value, (str, bytes)) else str(np.asarray(value).tolist())
    except Exception:                                  # noqa: BLE001 (anything that is not array-like)
        text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def finite_array(value):
    """`value` as a float64 array when it is numbers, all finite; None otherwise."""
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        return None
    return a if np.isfinite(a).all() else None


def checked_action(env, action, what):
    """An action as a (2,) float64 array, checked before the environment changes: a ValueError naming it unless it
    is 2 finite numbers."""
    a = finite_array(action)
    if a is None or a.shape != (2,):
        try:
            shape = np.shape(action)
        except Exception:                              # noqa: BLE001
            shape = None
        text = f"{shown(action)}" + (f" of shape {shape}" if shape not in (None, (2,)) else "")
        raise ValueError(f"{env}: the action ({what}) must be 2 finite numbers, got {text}")
    return a


def options_dict(env, options, allowed):
    """reset()'s options as a dict (None: none); a ValueError naming an option that is not one of `allowed`."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise ValueError(f"{env}: reset's options must be a dict (keys: {', '.join(allowed)}), got "
                         f"{type(options).__name__}")
    for k in options:
        if k not in allowed:
            raise ValueError(f"{env}: unknown reset option {k!r} (the options are {', '.join(allowed)})")
    return options
