"""Scene converters: 6.837 scene text -> tokens -> typed scene model -> Mitsuba scene dict / XML (SPEC A).

Only :mod:`a5mi.converters.to_mitsuba` (and the XML writer built on it) import Mitsuba, inside their functions;
lexing, parsing, the model and the scene description (:func:`a5mi.converters.describe.describe`: every file
read once) are pure Python, so scene and file errors never wait for a JIT backend.
"""

from a5mi.converters.a5_parser import parse_file, parse_text
from a5mi.converters.errors import FileLoc, SceneError, SceneSemanticError, SceneSyntaxError

__all__ = ["FileLoc", "SceneError", "SceneSemanticError", "SceneSyntaxError", "parse_file", "parse_text"]
