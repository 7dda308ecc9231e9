"""The render kernel's library: what every a5mi integrator traces with (SPEC B.3, A.6, docs/EXTENSIONS.md E.1-E.10).

An integrator builds two values once per call and hands them to its kernel:

* :class:`~.features.Features` (frozen, Python flags): which blocks the kernel contains. Built in one place,
  :func:`~.features.build_features`, from the integrator's parameters and the scene; inside ``@dr.syntax``
  code every optional block is written ``if dr.hint(features.x, mode='scalar'):`` (Mitsuba's ``prbvolpath``
  spelling), so a reader tells compile-time branches from per-lane ones at a glance. Two renders with equal
  features share one compiled kernel.
* :class:`~.features.SceneData` (per-scene values, all ``dr.opaque``): bounce budget, ambient, tmin, the
  lights, the planes, the triangle-rule table, the medium. Nothing of a scene is a kernel literal.

The modules, each usable alone:

=================== ====================================================================================
``features``        :class:`Features`, :class:`SceneData`, :func:`build_features`, :func:`stack_size`
``intersect``       :func:`intersect` (meshes by the binary's triangle and octree rules, spheres, exact
                    planes: one :class:`Hit`), :func:`mirror_normal`, :func:`visible` (the SPEC B.3 shadow
                    test ``S``, planes included)
``scene``           :class:`Lights` and :func:`lights_of` (one rule for "is a light", :func:`is_light`)
``lights``          :func:`direct` (the light loop: Σ S clamp(L·N, 0) lightColor ⊙ kd, E.2's samples),
                    :func:`sample` (one light sample: L, S, the term, the Phong highlight),
                    :func:`sample_point` (E.2's stratified sample), :func:`emission` (an area light seen
                    directly), :func:`record`
``surfaces``        :func:`surface_at` (the material through the vcall-able BSDF attributes, the bump
                    normal E.7, the dispersive index E.10), :func:`background`
``gloss``           :func:`facet` (E.4: the sampled GGX normal of a glossy child)
``stack``           :func:`create`, :func:`pop`, :func:`push`: the per-lane stack of pending rays of a
                    depth-first ray tree
``record``          :class:`TreeRecorder`: record mode, every node and term of a ray tree (``a5mi trace``)
``raylog``          :class:`RayLog`: every ray cast, for the benchmark's floor
``placing``         :func:`mistaken_normal`: docs/MISTAKES.md's normal-transform mistakes (N from the hit's
                    placing matrix)
=================== ====================================================================================

and, beside this package, the pieces they build on: ``plugins/optics.py`` (mirror, Snell, the Fresnel modes),
``plugins/emulation/octree_rule.py`` and ``plugins/emulation/triangle_rule.py`` (the binary's mesh rules),
``plugins/emulation/planes.py``,
``plugins/media/`` (E.8, E.9 media and their transmittance), ``plugins/materials/spectral.py`` (E.10),
``plugins/materials/bump.py`` (E.7), ``plugins/sampling.py`` (E.5). The kernels built on this library live
with their integrators: ``plugins/integrators/whitted/raytree.py`` (``a5_whitted``, SPEC B.3 read top to
bottom, with its medium and subsurface walks), ``path.py``, ``photon/``, ``irradiance_cache/``; the library
never imports them.
A new integrator imports these; it does not copy them. One Dr.Jit rule it must keep: a stack of
``dr.alloc_local`` arrays is carried through symbolic loops as a plain tuple (:mod:`.stack`).
"""
