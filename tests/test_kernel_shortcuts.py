"""framework/kernel_shortcuts: a cheaper cold compile; the code numba generates and its answers are unchanged."""
import os
import subprocess
import sys

# Kernels with what the shortcuts touch: arrays kept alive across branches and loops (the liveness that places
# numba's reference counts), user variables (their ABI sizes), numba's own overloads (np.empty) compiled inside
# ours, typing that tries templates that fail (the error text), a callee kernel. Prints a digest of each
# instance's optimised LLVM IR (numba's serial numbers in names taken out), and whether the collector ran
# during the compile and after it.
_CHILD = r"""
import gc, hashlib, os, re, sys
import numpy as np
from numba.core import event
from driftframe.framework.kernels import kernel
from driftframe.framework import kernel_shortcuts
if os.environ.get("EAGER_CODE") == "1":         # the pieces that leave numba's IR as it is (see below)
    kernel_shortcuts._code_on_demand = lambda ours: False

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def pick(a, k, flip):
    b = a[k]
    if flip:
        b = a[k + 1]
    return b

@kernel(error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
def blank(n):
    return np.empty(n, np.float64)

@kernel(error_model="numpy")
def outer(a, n, flip):
    out = np.empty(n, np.float64)
    out[0] = blank(n)[:1].size
    scratch = np.zeros(3, np.int64)
    total = 0.0
    for k in range(n - 1):
        row = pick(a, k, flip)
        if row[0] > 2.0:
            scratch[k % 3] += 1
            total += min(row[1], 1.5 * k)
        else:
            tail = a[k:]
            total -= tail[0, 2]
        out[k] = total
    out[n - 1] = scratch.sum()
    return out

gc_during = []
class Watch(event.Listener):
    def on_start(self, ev):
        gc_during.append(gc.isenabled())
    def on_end(self, ev):
        pass
event.register("numba:run_pass", Watch())
empties = []
class Empties(event.Listener):
    def on_start(self, ev):
        if ev.data["dispatcher"].py_func.__qualname__.startswith("ol_np_empty"):
            empties.append(str(ev.data["args"]))
    def on_end(self, ev):
        pass
event.register("numba:compile", Empties())

a = np.arange(15.0).reshape(5, 3)
got = [outer(a, 5, flip).tolist() for flip in (False, True)]
print("result", got)
def norm(t):
    return re.sub(r"_v\d+_", "_v_", re.sub(r"B\d+v\d+B", "BvB", t))
for d in (pick, blank, outer):
    for sig, cres in d.overloads.items():
        print(d.py_func.__name__, hashlib.sha256(norm(cres.library.get_llvm_str()).encode()).hexdigest())
print("installed", ",".join(kernel_shortcuts._installed))
print("gc during", any(gc_during), "after", gc.isenabled())
print("np.empty compiled", sorted(empties))
"""


def _child(on: str, tmp_path) -> list:
    # one hash seed for both: numba orders some reference-count increments by iterating sets of names
    env = dict(os.environ, DRIFTFRAME_COMPILE_SHORTCUTS=on, PYTHONHASHSEED="0", EAGER_CODE="1",
               NUMBA_CACHE_DIR=str(tmp_path / f"cache{on}"))
    out = subprocess.run([sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.split("\n")


def test_the_shortcuts_change_no_generated_code_and_can_be_turned_off(tmp_path):
    # (machine code on demand is left out here: a callee's module then reaches its callers before LLVM's code
    # generation passes have run on it, so their IR differs; its own test is below)
    on, off = _child("1", tmp_path), _child("0", tmp_path)
    assert "installed " in off and "gc during True after True" in off
    installed = next(ln for ln in on if ln.startswith("installed ")).split(" ", 1)[1].split(",")
    assert {"gc_paused", "liveness", "abi_size"} <= set(installed) and "code_on_demand" not in installed
    assert "gc during False after True" in on                   # paused while compiling, resumed after
    kept = ("installed", "gc during", "np.empty compiled")
    assert [ln for ln in on if not ln.startswith(kept)] == [ln for ln in off if not ln.startswith(kept)]
    assert sum(ln.startswith(("pick ", "blank ", "outer ")) for ln in on) == 3     # each compiled and compared
    # np.empty(n, np.float64) under a kernel with a CPython wrapper and one without: numba compiled it for each,
    # the shortcut once (the flags its compile inherits are the same)
    empties = {ln for ln in on + off if ln.startswith("np.empty compiled")}
    assert "overload_once" in installed and len(empties) == 2
    assert next(ln for ln in off if ln.startswith("np.empty")).count("float64") == 2
    assert next(ln for ln in on if ln.startswith("np.empty")).count("float64") == 1


# Callees with no wrapper (only other kernels call them), one that raises an exception numba builds at run time
# from the function's environment, two that call each other (numba's runtime linker), their callers; phases
# 2 and 3 load what phase 1 saved and compile one more caller of a saved callee.
_DEMAND_CHILD = r"""
import sys
import numpy as np
from driftframe.framework import kernel_shortcuts
from driftframe.framework.kernels import kernel

opts = dict(no_cpython_wrapper=True, no_cfunc_wrapper=True)

@kernel(error_model="numpy", **opts)
def pick(a, k):
    return a[k] * 2.0

@kernel(**opts)
def checked(x):
    if x < 0.0:
        raise ValueError("negative", x)
    return x

@kernel(**opts)
def even(n):
    if n == 0:
        return True
    return odd(n - 1)

@kernel(**opts)
def odd(n):
    if n == 0:
        return False
    return even(n - 1)

@kernel
def outer(a, n):
    s = 0.0
    for k in range(n):
        s += pick(a, k)[1]
    return s

@kernel
def guarded(x):
    return checked(x) * 2.0

@kernel
def parity(n):
    return even(n)

def code(*kernels):         # each compiled or loaded instance: whether its machine code is made
    return " ".join(f"{d.__name__}:{'pending' if getattr(c.library, '_code_pending', False) else 'made'}"
                    for d in kernels for c in d.overloads.values())

phase = sys.argv[1]
a = np.arange(15.0).reshape(5, 3)
print("outer", outer(a, 5), "guarded", guarded(1.5))
try:
    guarded(-1.5)
except ValueError as e:
    print("raised", e.args)
print("code", code(pick, checked, outer, guarded))
if phase == "1":                # (numba cannot load mutually recursive kernels from its cache, with or without)
    print("parity", parity(7), parity(10))
else:
    if phase == "2":
        @kernel
        def late(a, n):
            return pick(a, n)[2] + 0.5
    else:
        @kernel
        def late(a, n):
            return pick(a, n)[2] + 0.25
    print("late", late(a, 3), code(pick))
print("misses", sum(sum(d.stats.cache_misses.values()) for d in (outer, guarded)))
print("installed", ",".join(kernel_shortcuts._installed))
"""


def test_machine_code_is_made_when_asked_for_and_a_cache_without_it_loads_with_and_without_the_shortcuts(tmp_path):
    (tmp_path / "demand.py").write_text(_DEMAND_CHILD)

    def run(phase, on, cache):
        env = dict(os.environ, DRIFTFRAME_COMPILE_SHORTCUTS=on, NUMBA_CACHE_DIR=str(tmp_path / cache))
        out = subprocess.run([sys.executable, "demand.py", phase], env=env, capture_output=True, text=True,
                             timeout=300, cwd=tmp_path)
        assert out.returncode == 0, out.stderr[-2000:]
        return out.stdout.split("\n")

    ran = "outer 70.0 guarded 3.0", "raised ('negative', -1.5)"
    first = run("1", "1", "c")
    assert "code_on_demand" in first[-2]
    # the callees' code is not made (their callers carry it), the callers' is; all run as numba's own
    assert first[:5] == [*ran, "code pick:pending checked:pending outer:made guarded:made", "parity False True",
                         "misses 2"]
    assert run("1", "0", "off")[:5] == [*ran, "code pick:made checked:made outer:made guarded:made",
                                        "parity False True", "misses 2"]
    # loaded: a new caller of a callee saved without machine code links it (no code made for it either) ...
    assert run("2", "1", "c")[:5] == [*ran, "code outer:made guarded:made", "late 22.5 pick:pending", "misses 0"]
    # ... and without the shortcuts numba reads such a callee too (its code made as it loads)
    assert run("3", "0", "c")[:5] == [*ran, "code outer:made guarded:made", "late 22.25 pick:made", "misses 0"]


def _shortcuts(piece: str) -> bool:
    """Whether ``piece`` is installed in this process (kernels declared first); True unless turned off."""
    from driftframe.framework import kernel_shortcuts, kernels
    kernels.registry()
    off = os.environ.get("DRIFTFRAME_COMPILE_SHORTCUTS", "1") == "0"
    assert (piece in kernel_shortcuts._installed) is not off
    return not off


def _branchy(a, n, flip):                                        # (analysed, never compiled)
    out = a
    total = 0.0
    for k in range(n):
        b = a[k]
        if flip:
            b = a[k + 1]
            while total < 3.0:
                total += b[0]
        elif k > 2:
            out = b
        else:
            continue
        total += out[0]
    return total


def test_the_liveness_is_numba_s_own():
    from numba.core import analysis, compiler
    if not _shortcuts("liveness"):
        return
    ours, numbas = analysis.compute_live_map, analysis.compute_live_map.__wrapped__
    from driftframe.framework import contact_solve, kepler_kernels
    for f in (_branchy, contact_solve.solve_static.py_func, kepler_kernels._at_compiled.py_func):
        blocks = compiler.run_frontend(f).blocks
        cfg = analysis.compute_cfg_from_blocks(blocks)
        usedefs = analysis.compute_use_defs(blocks)
        want = numbas(cfg, blocks, usedefs.usemap, usedefs.defmap)
        assert ours(cfg, blocks, usedefs.usemap, usedefs.defmap) == want
        assert any(want.values())                                # (something is live across blocks)


def test_abi_sizes_are_llvm_s():
    from llvmlite import ir
    from numba.core import base
    from numba.core.registry import cpu_target
    if not _shortcuts("abi_size"):
        return
    ctx = cpu_target.target_context
    numbas = base.BaseContext.get_abi_sizeof.__wrapped__
    named = ir.global_context.get_identified_type("driftframe_test_named")
    if named.is_opaque:
        named.set_body(ir.IntType(8), ir.DoubleType())
    for ty in (ir.IntType(8), ir.DoubleType(), ir.LiteralStructType([ir.IntType(8), ir.DoubleType()]),
               ir.ArrayType(ir.IntType(32), 7), ir.IntType(8).as_pointer(), named):
        for _ in range(2):                                       # the second answer is the remembered one
            assert ctx.get_abi_sizeof(ty) == numbas(ctx, ty)


def test_error_text_is_numba_s_own():
    from driftframe.framework import kernel_shortcuts
    from numba.core import errors
    _shortcuts("liveness")                                       # (declared, installed unless turned off)
    scheme = getattr(errors, "HighlightColorScheme", None)
    if scheme is None:                                           # numba without colorama: plain text, nothing replaced
        assert "markup" not in kernel_shortcuts._installed
        return
    if not _shortcuts("markup"):
        return
    paint = errors.termcolor()
    for msg in ("Cannot determine Numba type of <class 'object'>", "", "é ✓"):
        for color in (None, errors.Fore.RED):
            assert paint._markup(msg, color) == scheme._markup.__wrapped__(paint, msg, color)
        assert paint.errmsg(msg) == scheme._markup.__wrapped__(paint, msg, paint._errmsg)


def test_the_collector_stays_off_when_the_user_turned_it_off(tmp_path):
    code = ("import gc, numpy as np\n"
            "from driftframe.framework.kernels import kernel\n"
            "@kernel\n"
            "def f(a):\n"
            "    return a.sum()\n"
            "gc.disable()\n"
            "f(np.ones(3))\n"
            "print(gc.isenabled())\n")
    env = dict(os.environ, DRIFTFRAME_COMPILE_SHORTCUTS="1", NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip() == "False"
