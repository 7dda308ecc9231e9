"""Rendering: what a render needs and may do, from the options to the image (the driver, its passes, tiles, bands
and filters after the restructuring). May import :mod:`a5mi.options`, :mod:`a5mi.resources`, :mod:`a5mi.errors`
and the plugins; never the command layer (``a5mi.cli``, ``a5mi.commands``) nor the view."""
