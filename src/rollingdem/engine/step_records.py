"""The step loop's records behind one reference, for the threaded passes' parallel loops.

Numba hands each variable a parallel loop reads to its threads as an argument of its own, and a
record's arrays one by one: a loop reading the particles', walls' and list's records (84 arrays)
compiled 2-3 s slower than one reading a reference to them. The loops' bodies read the records from
the reference (``gather_chunk``, ``pair_chunk``)."""

from numba import types
from numba.experimental import structref


@structref.register
class StepRecordsType(types.StructRef):
    def preprocess_fields(self, fields):
        return tuple((name, types.unliteral(typ)) for name, typ in fields)


class StepRecords(structref.StructRefProxy):
    """The particles', walls' and list's records (``EngineState.records``) as one reference, made
    in compiled code only."""


class PairRecords(structref.StructRefProxy):
    """The particles', list's and scratch records as one reference, made in compiled code only."""


structref.define_constructor(StepRecords, StepRecordsType, ["particles", "walls", "lists"])
structref.define_constructor(PairRecords, StepRecordsType, ["particles", "lists", "scratch"])
