"""Readers for the third-party LCP corpus in ../shared/data/lcp (Siconos .dat files and lcp_instances.json).

The data is not part of this repository; `find_corpus_dir` looks for it and returns None when it is absent.
"""

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class LCPInstance:
    id: str
    source: str
    M: np.ndarray
    q: np.ndarray
    expected: str
    known_z: np.ndarray | None = None
    note: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return self.q.shape[0]


def expectation(expected: str) -> str:
    """Map the corpus's free-text `expected` field to what a Lemke solver with covering vector e must do.

    Returns "solved" or "failure" (a ray termination or other reported failure: never a wrong z)."""
    e = expected.strip()
    if e.startswith("solved"):
        return "solved"
    if e.startswith("secondary_ray with d=(5,16); solved with d=(1,1)"):
        return "solved"  # we use d = e = (1, 1)
    if e.startswith(("lemke_fails", "fails", "secondary_ray", "infeasible")):
        return "failure"
    if e.startswith("pivot_fails"):
        # Siconos's *pivot* solver fails on it; a solution exists and lexicographic Lemke must find it.
        return "solved"
    raise ValueError(f"lcp_corpus: unknown 'expected' value {expected!r}")


def find_corpus_dir() -> Path | None:
    """../shared/data/lcp relative to the repository (or $PLANAR_LCP_CORPUS), or None if absent."""
    env = os.environ.get("PLANAR_LCP_CORPUS")
    candidates = [Path(env)] if env else []
    here = Path(__file__).resolve().parent
    for up in (here.parent, here.parent.parent, Path.cwd(), Path.cwd().parent):
        candidates.append(up / ".." / "shared" / "data" / "lcp")
        candidates.append(up / "shared" / "data" / "lcp")
    for c in candidates:
        if (c / "lcp_instances.json").is_file():
            return c.resolve()
    return None


class DatFormatError(ValueError):
    pass


def _numbers_until_comment(path: Path) -> list[str]:
    toks: list[str] = []
    for line in path.read_text().splitlines():
        s = line.strip()
        if s.startswith("#"):
            break
        toks.extend(s.split())
    return toks


class _Tokens:
    def __init__(self, path: Path, toks: list[str]):
        self.path, self.toks, self.i = path, toks, 0

    def take(self, what: str) -> str:
        if self.i >= len(self.toks):
            raise DatFormatError(f"{self.path}: unexpected end of file while reading {what}")
        t = self.toks[self.i]
        self.i += 1
        return t

    def _number(self, what: str, kind, noun: str):
        t = self.take(what)
        try:
            return kind(t)
        except ValueError:
            raise DatFormatError(f"{self.path}: {what} must be {noun}, got {t!r}") from None

    def int(self, what: str) -> int:
        return self._number(what, int, "an integer")

    def float(self, what: str) -> float:
        return self._number(what, float, "a number")

    def floats(self, count: int, what: str) -> np.ndarray:
        return np.array([self.float(f"{what}[{k}]") for k in range(count)])


def _read_matrix(tk: _Tokens, what: str) -> np.ndarray:
    """Siconos NumericsMatrix: storage 0 = dense (column-major), 1 = sparse block."""
    storage = tk.int(f"{what} storageType")
    size0 = tk.int(f"{what} size0")
    size1 = tk.int(f"{what} size1")
    if storage == 0:
        r = tk.int(f"{what} dense rows")
        c = tk.int(f"{what} dense cols")
        if (r, c) != (size0, size1):
            raise DatFormatError(f"{tk.path}: {what} dense size must repeat ({size0}, {size1}), got ({r}, {c})")
        vals = tk.floats(r * c, f"{what} values")
        return vals.reshape((c, r)).T.copy()  # column-major: each text line is a column
    if storage == 1:
        nb = tk.int(f"{what} nbblocks")
        nbr = tk.int(f"{what} nbBlockRows")
        nbc = tk.int(f"{what} nbBlockCols")
        row_cum = [tk.int(f"{what} blockRowCumSizes[{k}]") for k in range(nbr)]
        col_cum = [tk.int(f"{what} blockColCumSizes[{k}]") for k in range(nbc)]
        filled1 = tk.int(f"{what} filled1")
        filled2 = tk.int(f"{what} filled2")
        index1 = [tk.int(f"{what} index1_data[{k}]") for k in range(filled1)]
        index2 = [tk.int(f"{what} index2_data[{k}]") for k in range(filled2)]
        if filled2 != nb:
            raise DatFormatError(f"{tk.path}: {what} filled2 must equal nbblocks = {nb}, got {filled2}")
        M = np.zeros((size0, size1))
        row_start = [0] + row_cum[:-1]
        col_start = [0] + col_cum[:-1]
        # index1_data is the CSR row pointer over block rows, index2_data the block column of each block
        for br in range(nbr):
            for k in range(index1[br], index1[br + 1]):
                bc = index2[k]
                kk = tk.int(f"{what} block number")
                if kk != k:
                    raise DatFormatError(f"{tk.path}: {what} block number must be {k}, got {kk}")
                nr = row_cum[br] - row_start[br]
                ncl = col_cum[bc] - col_start[bc]
                vals = tk.floats(nr * ncl, f"{what} block {k} values")
                M[row_start[br]:row_cum[br], col_start[bc]:col_cum[bc]] = vals.reshape((ncl, nr)).T
        return M
    raise DatFormatError(f"{tk.path}: {what} storageType must be 0 (dense) or 1 (sparse block), got {storage}")


def read_siconos_lcp(path) -> tuple[np.ndarray, np.ndarray]:
    """Read a Siconos LCP .dat file: n, the matrix M, then q. Returns (M, q)."""
    path = Path(path)
    tk = _Tokens(path, _numbers_until_comment(path))
    n = tk.int("n")
    M = _read_matrix(tk, "M")
    if M.shape != (n, n):
        raise DatFormatError(f"{path}: M must be {n}x{n}, got {M.shape[0]}x{M.shape[1]}")
    q = tk.floats(n, "q")
    return M, q


def read_siconos_fc2d(path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a Siconos 2-D friction-contact .dat file. Returns (W, q, mu); per contact (normal, tangent)."""
    path = Path(path)
    tk = _Tokens(path, _numbers_until_comment(path))
    dim = tk.int("dimension")
    if dim != 2:
        raise DatFormatError(f"{path}: dimension must be 2, got {dim}")
    nc = tk.int("number of contacts")
    W = _read_matrix(tk, "W")
    if W.shape != (2 * nc, 2 * nc):
        raise DatFormatError(f"{path}: W must be {2 * nc}x{2 * nc}, got {W.shape}")
    q = tk.floats(2 * nc, "q")
    mu = tk.floats(nc, "mu")
    return W, q, mu


def load_json_instances(corpus_dir) -> list[LCPInstance]:
    path = Path(corpus_dir) / "lcp_instances.json"
    data = json.loads(path.read_text())
    out = []
    for k, d in enumerate(data["instances"]):
        M = np.array(d["M"], dtype=np.float64)  # row-major list of rows
        q = np.array(d["q"], dtype=np.float64)
        n = int(d["n"])
        if M.shape != (n, n) or q.shape != (n,):
            raise DatFormatError(f"{path}: instances[{k}] ({d['id']}): M must be {n}x{n} and q length {n}, "
                                 f"got {M.shape} and {q.shape}")
        kz = d.get("known_z")
        out.append(LCPInstance(id=d["id"], source=d["source"], M=M, q=q, expected=d["expected"],
                               known_z=None if kz is None else np.array(kz, dtype=np.float64),
                               note=d.get("note", ""), extra=d))
    return out


def load_corpus(corpus_dir=None) -> list[LCPInstance]:
    """All JSON instances (their Siconos members cross-checked against the .dat files by the tests)."""
    corpus_dir = corpus_dir or find_corpus_dir()
    if corpus_dir is None:
        return []
    return load_json_instances(corpus_dir)
