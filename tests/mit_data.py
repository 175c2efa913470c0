"""Where the tests find the MIT pushing data set (read from ../shared, never copied into the repository), and the
mark that skips a test cleanly when it is absent."""

from pathlib import Path

import pytest

from planar_lcp.studies.pushdata import mit

ROOT = Path(__file__).resolve().parent.parent


def _data_root():
    """The data: $PLANAR_LCP_MIT_PUSH, else ../shared/data/mit-push beside this checkout (or one folder further up,
    for a checkout in a folder of worktrees)."""
    found = mit.find_data_root()
    if found is not None:
        return found
    for up in (ROOT / "..", ROOT / ".." / ".."):
        if (up / "shared" / "data" / "mit-push" / "objects").is_dir():
            return (up / "shared" / "data" / "mit-push").resolve()
    return None


DATA = _data_root()
needs_data = pytest.mark.skipif(DATA is None, reason="the MIT push data (../shared/data/mit-push) is absent: set "
                                                     "PLANAR_LCP_MIT_PUSH to its folder")
