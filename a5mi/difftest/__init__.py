"""Differential testing of a5mi against any executable with the a5 command line (docs/DIFFTEST.md).

:mod:`.generate` draws seeded random scenes from the SPEC grammar; :mod:`.runner` renders one with both
renderers (the other one sandboxed, in its own folder, with a time limit) and compares the 8-bit images;
:mod:`.minimise` shrinks a failing scene to a smallest reproducer.
"""
