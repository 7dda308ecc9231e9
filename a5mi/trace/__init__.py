"""a5mi trace: the SPEC B.3 ray tree of one pixel, recorded by the render kernel itself (docs: README, trace)."""
