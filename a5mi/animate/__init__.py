"""Keyframed animation and motion blur (docs/EXTENSIONS.md E.11, E.12).

* :mod:`.warm`: one warm Mitsuba scene per process, updated per frame through ``mi.traverse`` (no kernel
  recompilation), and the motion-blur rule of E.12;
* :mod:`.frames`: numbered frame images written atomically with a SHA-256 file beside each, and the scan that
  tells ``--resume`` which frames are missing or damaged;
* :mod:`.batch`: frames rendered in this process or in contiguous chunks on Dask workers (:mod:`a5mi.runtime.cluster`,
  the backend of ``a5mi grade``), each worker keeping its warm scene;
* :mod:`.video`: frames to MP4 / GIF with ``imageio-ffmpeg``.

Libraries only: nothing here prints (``a5mi.commands.animate`` does).
"""
