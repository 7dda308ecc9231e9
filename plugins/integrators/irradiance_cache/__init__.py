"""``a5_irradiancecache`` (EXTENSIONS E.23): Ward's record formulas (``formulas``), their grid
(``grid``), the gather kernel (``kernel``) and the integrator (``integrator``).

May import: :mod:`a5mi.plugins.kernel` and the lower plugin packages.
"""
