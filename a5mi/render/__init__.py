"""The render stage: options, passes, tiles, bands and the driver that turns a loaded scene into images, and the
work estimate made before a render starts. Modules here may import :mod:`a5mi.platform`, :mod:`a5mi.spec`,
:mod:`a5mi.options` and the scene description of :mod:`a5mi.converters`; never the command layer
(:mod:`a5mi.cli`, :mod:`a5mi.commands`), which calls them."""
