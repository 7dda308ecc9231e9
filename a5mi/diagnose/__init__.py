"""``a5mi diagnose``'s library: name the student mistake that explains an image's difference (docs/MISTAKES.md).

:mod:`a5mi.diagnose.catalogue` lists the mistakes (each an exact change to SPEC's computation, with its symptom and
what a scene and the flags need for it to show); :mod:`a5mi.diagnose.rank` renders the reference and the mutants
(``RenderOptions.mistakes``) in one warm :class:`~a5mi.render.session.RenderSession` and ranks them by the share of the
difference each explains (:func:`a5mi.diagnose.rank.diagnose`); :mod:`a5mi.diagnose.probes` holds the probe scenes
that tell every pair of mistakes apart, for ``--binary``. May import a5mi's render, session, options, compare,
imageio and sandbox modules; never the command layer, never prints.
"""
