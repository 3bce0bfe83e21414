"""The inliner's one-copy fix (``engine.numba_inlining``): installed on the Numba this package runs
with, left out on a Numba whose source differs, and the inlined code computing what it computed."""

import pytest
from numba import njit
from numba.core import inline_closurecall

from rollingdem.engine import numba_inlining


def test_the_one_copy_is_installed_on_this_numba():
    # the installed Numba still copies a callee block by block: rollingdem's import swapped that copy
    # for one deep copy of the whole function (if this fails, Numba changed and the fix is not used)
    assert getattr(inline_closurecall.InlineWorker.inline_ir, "one_scope_copy", False)
    assert numba_inlining.use_one_scope_copy()


def test_a_numba_of_other_source_is_left_as_it_is(monkeypatch):
    def inline_ir(self, caller_ir, block, i, callee_ir, callee_freevars, arg_typs=None):
        return "another version"

    monkeypatch.setattr(inline_closurecall.InlineWorker, "inline_ir", inline_ir)
    assert not numba_inlining.use_one_scope_copy()
    assert inline_closurecall.InlineWorker.inline_ir is inline_ir


@njit(inline="always")
def _branchy(x, k):
    # blocks and variables enough for each copy to matter, and a loop whose variables the caller
    # shares names with
    s = 0.0
    for q in range(k):
        if q % 3 == 0:
            s += x * q
        elif q % 3 == 1:
            s -= x / (q + 1.0)
        else:
            s *= 0.5
    return s


@njit
def _caller(x):
    s = 0.0
    for q in range(4):
        s += _branchy(x + q, 7) - _branchy(x - q, 5)
    return s


def _plain(x):
    return sum(_branchy.py_func(x + q, 7) - _branchy.py_func(x - q, 5) for q in range(4))


@pytest.mark.parametrize("x", [0.3, -2.0, 11.5])
def test_inlined_twice_in_a_loop_it_computes_what_python_does(x):
    # the same operations in the same order: equal to the bit
    assert _caller(x) == _plain(x)
