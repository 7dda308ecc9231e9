"""``a5mi view``: the live page (docs/VIEW.md): one warm render session behind a token-guarded local web server.

* :mod:`.engine`: the scene, its render (SPEC B.1-B.5, the bytes ``a5`` would write), the reference (an image or
  another binary's render, sandboxed), ``compare``'s metrics and heatmap, and ``trace``'s ray tree of a pixel;
  everything Mitsuba runs on the one thread that owns the engine.
* :mod:`.watcher`: the files the scene description read, polled for changes (mtime and size).
* :mod:`.server`: the HTTP routes, the token check, server-sent events and the job queue to the engine.
* ``static/``: the page (HTML, JS, CSS), served from package data: no network.
"""
