"""Scene converters: 6.837 scene text -> tokens -> typed scene model -> Mitsuba scene dict / XML (SPEC A).

Only :mod:`a5mi.converters.to_mitsuba` (and the XML writer built on it) import Mitsuba; lexing, parsing and
the model are pure Python, so syntax errors never wait for a JIT backend.
"""
