"""Numba's inliner copies a callee's IR with one scope per block: ``inline_ir`` deep-copies each block
on its own, and each copy takes a copy of the whole function's scope (every variable), so inlining
costs blocks x variables. The contact law, inlined through four levels into the pair pass, the
scalar contact and the gather, spends about half of its compile there (numba/numba#8989, #9204).

``use_one_scope_copy`` makes the copy one deep copy of all the blocks, sharing one copied scope as
the original blocks share theirs: the same IR, the copy made once. It changes Numba only where its
source is the text below (the versions this package was measured with); any other version is left
as it is."""

from __future__ import annotations

import inspect
import textwrap

from numba.core import inline_closurecall

PER_BLOCK_COPY = """\
        kernel_copy.blocks = {}
        for block_label, block in the_ir.blocks.items():
            new_block = copy.deepcopy(the_ir.blocks[block_label])
            kernel_copy.blocks[block_label] = new_block
"""
ONE_COPY = """\
        kernel_copy.blocks = copy.deepcopy(the_ir.blocks)
"""


def use_one_scope_copy() -> bool:
    """Install the one-copy ``InlineWorker.inline_ir``; True if it is installed (now or before)."""
    worker = inline_closurecall.InlineWorker
    if getattr(worker.inline_ir, "one_scope_copy", False):
        return True
    try:
        source = textwrap.dedent(inspect.getsource(worker.inline_ir))
    except (OSError, TypeError):
        return False
    if source.count(PER_BLOCK_COPY) != 1:
        return False
    namespace = dict(vars(inline_closurecall))
    exec(compile(source.replace(PER_BLOCK_COPY, ONE_COPY), inline_closurecall.__file__, "exec"), namespace)
    inline_ir = namespace["inline_ir"]
    inline_ir.one_scope_copy = True
    worker.inline_ir = inline_ir
    return True


use_one_scope_copy()
