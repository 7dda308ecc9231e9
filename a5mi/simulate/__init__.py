"""Simulations whose frames a scene can play back (docs/EXTENSIONS.md E.22).

* :mod:`.smoke`: stable fluids (Stam 1999) on a periodic ``N³`` grid, numpy only: semi-Lagrangian advection,
  buoyancy, vorticity confinement and an exact FFT projection; each frame's smoke density is written as a
  Mitsuba ``.vol`` grid (:mod:`a5mi.converters.volgrid`) for a keyframed ``Volume { grid "smoke_%03d.vol" }``.

Libraries only: nothing here prints (``a5mi.commands.simulate`` does).
"""
