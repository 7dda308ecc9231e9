"""``python -m a5mi.mitsuba SCENE.xml -o IMG [-D NAME=VALUE ...]``: ``a5mi render-xml``
(:mod:`a5mi.commands.render_xml`)
for Mitsuba users: renders any Mitsuba 3 XML with the a5mi plugins registered."""

from __future__ import annotations

import sys

if __name__ == "__main__":
    from a5mi.cli import run_a5mi

    sys.exit(run_a5mi(["render-xml", *sys.argv[1:]]))
