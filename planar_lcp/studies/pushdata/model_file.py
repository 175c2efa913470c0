"""The push model file (MODEL.json): the parameters of `mit.push_scene`, as `planar-lcp pushdata fit` writes them and
`planar-lcp pushdata predict --model` reads them (docs/real_pushes.md, "Fitting").

A JSON object:

- ``format``: "planar_lcp.push_model"; ``version``: 1 (required);
- ``parameters``: {name: value} (required): names among the keys of `mit.DEFAULT_PARAMS` (support_friction,
  pusher_friction: Coulomb coefficients, >= 0; h: the time step, s, in (0, 0.05]); a parameter the file does not
  give takes its DEFAULT_PARAMS value; `fit` writes them all;
- and what a fit records (optional, any may be absent in a file written by hand): ``stderr`` and ``stderr_by_run``
  ({name: standard error} of the fitted parameters: classical, and clustered by push), ``fitted_on`` (the push
  files' names), ``objects`` (their objects), ``cost`` (half the sum of squared residuals, m^2), ``per_push`` (a
  list of per-push errors at the fitted values), ``scores`` (those of `score` over the pushes), ``settings`` (an
  object: how the fit ran), ``command`` (the command line that wrote it), ``description`` (free text).

`read_model` checks every rule and raises ModelFileError, one line naming the file, the field, what was expected and
what was found; `write_model` writes the same format.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

FORMAT = "planar_lcp.push_model"
VERSION = 1

#: name -> (low, low included, high, high included): the range of each parameter a model file may give
RANGES = {"support_friction": (0.0, True, math.inf, False), "pusher_friction": (0.0, True, math.inf, False),
          "h": (0.0, False, 0.05, True),
          # parameters of the support pressure and the inertia, where mit.push_scene takes them
          "ring_share": (0.0, True, 1.0, True), "ring_scale": (0.0, False, 1.0, True),
          "inertia_scale": (0.0, False, math.inf, False)}

_OPTIONAL = {"stderr": dict, "stderr_by_run": dict, "fitted_on": list, "objects": list, "cost": (int, float),
             "per_push": list, "scores": dict, "settings": dict, "command": str, "description": str}


class ModelFileError(ValueError):
    """A model file that cannot be used: one line naming the file, the field, the expected and the actual."""


@dataclass
class PushModel:
    """A model file's content: `parameters` complete (every key of mit.DEFAULT_PARAMS), the rest as the file gives
    it (None or empty when absent)."""

    parameters: dict
    stderr: dict = field(default_factory=dict)
    stderr_by_run: dict = field(default_factory=dict)
    fitted_on: list = field(default_factory=list)
    objects: list = field(default_factory=list)
    cost: float | None = None
    per_push: list = field(default_factory=list)
    scores: dict = field(default_factory=dict)
    settings: dict = field(default_factory=dict)
    command: str | None = None
    description: str | None = None
    source: str = ""


def _known():
    from planar_lcp.studies.pushdata.mit import DEFAULT_PARAMS
    return DEFAULT_PARAMS


def _range_text(name):
    lo, lo_in, hi, hi_in = RANGES[name]
    if hi == math.inf:
        return f"{'>=' if lo_in else '>'} {lo:g}"
    return f"in {'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"


def check_parameter(name, value, where):
    """`value` as a float if `name` is a known parameter and `value` a finite number in its range; else
    ModelFileError naming `where` (e.g. "MODEL.json: parameters.support_friction")."""
    known = _known()
    if name not in known:
        raise ModelFileError(f"{where}: unknown parameter {name!r} (known: {', '.join(known)})")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ModelFileError(f"{where}: must be a finite number, got {json.dumps(value)}")
    value = float(value)
    if name in RANGES:
        lo, lo_in, hi, hi_in = RANGES[name]
        if not ((value >= lo if lo_in else value > lo) and (value <= hi if hi_in else value < hi)):
            raise ModelFileError(f"{where}: must be {_range_text(name)}, got {value:g}")
    return value


def read_model(path) -> PushModel:
    """Read and check a model file (module docstring); ModelFileError naming the file and the field."""
    path = Path(path)
    src = str(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ModelFileError(f"{src}: no such model file") from None
    except IsADirectoryError:
        raise ModelFileError(f"{src}: must be a model file (JSON), got a directory") from None
    except UnicodeDecodeError as e:
        raise ModelFileError(f"{src}: must be UTF-8 JSON, got byte {e.object[e.start]:#04x} at offset {e.start}") \
            from None
    except OSError as e:
        raise ModelFileError(f"{src}: cannot be read: {e.strerror or e}") from None
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise ModelFileError(f"{src}: must be JSON, got {e.msg} at line {e.lineno}, column {e.colno}") from None
    if not isinstance(doc, dict):
        raise ModelFileError(f"{src}: must be a JSON object, got {type(doc).__name__ if doc is not None else 'null'}")
    if doc.get("format") != FORMAT:
        raise ModelFileError(f"{src}: format must be {FORMAT!r}, got "
                             f"{json.dumps(doc['format']) if 'format' in doc else 'no format field'}")
    if doc.get("version") != VERSION or isinstance(doc.get("version"), bool):
        raise ModelFileError(f"{src}: version must be {VERSION}, got "
                             f"{json.dumps(doc['version']) if 'version' in doc else 'no version field'}")
    allowed = {"format", "version", "parameters", *_OPTIONAL}
    extra = sorted(set(doc) - allowed)
    if extra:
        fields = ", ".join(["format", "version", "parameters", *_OPTIONAL])
        raise ModelFileError(f"{src}: unknown field {extra[0]!r} (fields: {fields})")
    if "parameters" not in doc:
        raise ModelFileError(f"{src}: must have a 'parameters' object ({{name: value}}), got none")
    given = doc["parameters"]
    if not isinstance(given, dict):
        raise ModelFileError(f"{src}: parameters must be an object {{name: value}}, got {json.dumps(given)}")
    params = dict(_known())
    for name, value in given.items():
        params[name] = check_parameter(name, value, f"{src}: parameters.{name}")
    out = {}
    for key, kind in _OPTIONAL.items():
        if key not in doc or doc[key] is None:
            continue
        value = doc[key]
        if isinstance(value, bool) or not isinstance(value, kind):
            expected = {dict: "an object", list: "a list", str: "a string"}.get(kind, "a number")
            raise ModelFileError(f"{src}: {key} must be {expected}, got {json.dumps(value)[:60]}")
        if key in ("stderr", "stderr_by_run"):
            for name, v in value.items():
                if name not in params:
                    raise ModelFileError(f"{src}: {key}.{name}: unknown parameter {name!r} (known: "
                                         f"{', '.join(params)})")
                if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
                    raise ModelFileError(f"{src}: {key}.{name} must be a number, got {json.dumps(v)}")
        if key in ("fitted_on", "objects") and not all(isinstance(v, str) for v in value):
            raise ModelFileError(f"{src}: {key} must be a list of strings, got {json.dumps(value)[:60]}")
        out[key] = value
    if "cost" in out:
        out["cost"] = float(out["cost"])
    return PushModel(parameters=params, source=src, **out)


def _jsonable(x):
    """NaN and infinities as null (JSON has none), numpy scalars as Python numbers."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if hasattr(x, "item") and not isinstance(x, (str, bytes)):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def write_model(path, parameters, *, stderr=None, stderr_by_run=None, fitted_on=(), objects=(), cost=None,
                per_push=(), scores=None, settings=None, command=None, description=None) -> dict:
    """Write a model file (module docstring) and return its document. `parameters` is checked as `read_model`
    checks it (ModelFileError); a parameter not given takes its DEFAULT_PARAMS value."""
    params = dict(_known())
    for name, value in parameters.items():
        params[name] = check_parameter(name, value, f"{path}: parameters.{name}")
    doc = {"format": FORMAT, "version": VERSION, "parameters": params,
           "stderr": dict(stderr or {}), "stderr_by_run": dict(stderr_by_run or {}), "fitted_on": list(fitted_on),
           "objects": list(objects), "cost": cost, "per_push": list(per_push), "scores": dict(scores or {}),
           "settings": dict(settings or {}), "command": command}
    if description is not None:
        doc["description"] = description
    doc = _jsonable(doc)
    Path(path).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return doc
