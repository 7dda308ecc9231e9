"""The sample solution's own rules, reproduced exactly (SPEC C): the octree walk of rays
(``octree_rule``, ``octree_leaves``), the float32 triangle test (``triangle_rule``) and the analytic planes
and spheres with their float32 inverses (``planes``).

May import: the :mod:`a5mi.plugins` leaves, the a5mi leaves.
"""
