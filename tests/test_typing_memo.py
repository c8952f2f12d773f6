"""framework/typing_memo: numba's typing of a call remembered per process; the code numba generates is unchanged."""
import os
import subprocess
import sys

import pytest

# A kernel with what driftframe's kernels are made of (2-D indexing, an overload compiled under the caller's
# flags, Python's min, a call to another kernel with a literal turned into an int64), twice under other flags.
# Prints a digest of each instance's optimised LLVM IR, with numba's serial numbers in names taken out.
_CHILD = r"""
import hashlib, re, sys
import numpy as np
from driftframe.framework.kernels import kernel
from numba.core.types import functions

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def inner(a, k):
    return a[k, 0] + a[k, 1]

@kernel(error_model="numpy")
def outer(a, n):
    out = np.empty(n, np.float64)
    for k in range(n):
        out[k] = min(inner(a, np.int64(k)), a[k, 2] / 3.0)
    return out

@kernel(error_model="python")
def outer_py(a, n):
    out = np.empty(n, np.float64)
    for k in range(n):
        out[k] = min(inner(a, np.int64(k)), a[k, 2] / 3.0)
    return out

a = np.arange(12.0).reshape(4, 3)
assert outer(a, 4).tolist() == outer_py(a, 4).tolist() == [min(a[k, 0] + a[k, 1], a[k, 2] / 3.0) for k in range(4)]
def norm(t):
    return re.sub(r"_v\d+_", "_v_", re.sub(r"B\d+v\d+B", "BvB", t))
for d in (outer, outer_py):
    for sig, cres in d.overloads.items():
        print(d.py_func.__name__, hashlib.sha256(norm(cres.library.get_llvm_str()).encode()).hexdigest())
print("wrapped", hasattr(functions.BaseFunction.get_call_type, "__wrapped__"))
print("answered", getattr(functions.BaseFunction.get_call_type, "answered", [0])[0] > 0)
"""


def _child(memo: str, tmp_path) -> list:
    env = dict(os.environ, DRIFTFRAME_TYPING_MEMO=memo, NUMBA_CACHE_DIR=str(tmp_path / f"cache{memo}"))
    out = subprocess.run([sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.split("\n")


def test_the_memo_changes_no_generated_code_and_can_be_turned_off(tmp_path):
    on, off = _child("1", tmp_path), _child("0", tmp_path)
    assert "wrapped True" in on and "wrapped False" in off
    assert "answered True" in on                                # the memo did answer calls (the two instances share them)
    kept = ("wrapped", "answered")
    assert [ln for ln in on if not ln.startswith(kept)] == [ln for ln in off if not ln.startswith(kept)]
    assert sum(ln.startswith("outer") for ln in on) == 2          # both instances were compiled and compared


def test_a_call_that_does_not_type_is_numba_s_own_error():
    from numba.core.errors import TypingError

    from driftframe.framework import kernels, typing_memo
    kernels.registry()                                           # kernels declared: the memo installed
    assert typing_memo.install() is (os.environ.get("DRIFTFRAME_TYPING_MEMO", "1") != "0")

    import numba

    @numba.njit                                                  # (not a driftframe kernel: none is added)
    def bad(a):
        return a["x"] + 1

    import numpy as np
    for _ in range(2):                                           # a failure is not remembered: the same error again
        with pytest.raises(TypingError, match="getitem"):
            bad(np.zeros(3))
