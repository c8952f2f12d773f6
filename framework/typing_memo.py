"""numba's typing of a call, remembered: the same function, argument types and compile flags resolve once per process.

numba types every call in a kernel (``a[i, 0]``, ``x + y``, ``np.empty(n, np.int64)``, ...) by trying the
function's templates in turn until one accepts the argument types (``BaseFunction.get_call_type``), and it
does so again for every call site, in every kernel, and once more while lowering an array index: nothing
remembers the answer. Most of a cold compile is such work in Python (the profile in docs/bench/compile.md),
and the same few hundred resolutions repeat thousands of times. :func:`install` wraps ``get_call_type``
with a dictionary keyed by everything the answer depends on: the function type (its key holds its
templates, so a function given another overload later is another type), the argument types (literals
included), the keyword types, the typing context, and the flags of the compile in progress (an overload's
implementation is compiled under them: ``error_model``, ``fastmath``, ...). Only answers are kept; a call
that fails to type goes to numba every time, so its error is numba's own.

What it changes: nothing in the code numba generates (checked: the optimised LLVM IR of every kernel
instance ``driftframe warm`` compiles, with and without, equal up to numba's serial numbers in symbol
names and the order of two reference-count increments), only the time a cold compile takes
(docs/bench/compile.md). ``DRIFTFRAME_TYPING_MEMO=0`` leaves numba as it is; so does a numba whose
internals differ from those this was written for (the method's parameters and the flags' ``_values`` are
checked first).
"""
from __future__ import annotations

import os

_installed = False


def install() -> bool:
    """Wrap numba's ``BaseFunction.get_call_type`` (once per process); False where it was left alone."""
    global _installed
    if _installed:
        return True
    if os.environ.get("DRIFTFRAME_TYPING_MEMO", "1") == "0":
        return False
    try:
        import inspect

        from numba.core import targetconfig
        from numba.core.types import functions
        original = functions.BaseFunction.get_call_type
        if list(inspect.signature(original).parameters) != ["self", "context", "args", "kws"]:
            return False
        top = targetconfig.ConfigStack.top_or_none
        if not hasattr(targetconfig.TargetConfig(), "_values"):
            return False
    except (ImportError, AttributeError, TypeError, ValueError):
        return False

    memo: dict = {}
    answered = [0]                              # calls answered from the memo (what the tests look at)

    def get_call_type(self, context, args, kws):
        flags = top()
        try:
            key = (self, tuple(args), tuple(kws.items()), context,
                   None if flags is None else tuple(sorted(flags._values.items())))
            sig = memo.get(key)
        except TypeError:                       # an unhashable type: numba's own way
            return original(self, context, args, kws)
        if sig is not None and sig.args in self._impl_keys:
            answered[0] += 1
            return sig
        sig = original(self, context, args, kws)
        if sig is not None:
            memo[key] = sig
        return sig

    get_call_type.__wrapped__ = original
    get_call_type.answered = answered
    functions.BaseFunction.get_call_type = get_call_type
    _installed = True
    return True
