"""Sensor plugins: ``a5_camera`` (SPEC A.1 perspective camera, B.2 pixel rays).

May import: the :mod:`a5mi.plugins` leaves, the a5mi leaves.
"""
