"""The step loop's template, one part per pass: ``contact`` (the contact law's functions and row
layout, the lines tagged ``# @@``; one contact), ``pairs`` (the pair pass), ``walls`` (a particle's
wall and mesh contacts), ``gather`` (the gather, the kicks, the bonds' pass) and ``loop`` (the step
loop). ``rollingdem.engine.codegen`` writes them, in that order, into one module per contact law,
the tagged lines filled in and the imports between parts (tagged ``# @@PART``) left out."""

PARTS = ("contact", "pairs", "walls", "gather", "loop")
