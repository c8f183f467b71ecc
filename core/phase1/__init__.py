"""Phase 1 (the thesis' method for ball lenses): image points, spreading angles, brightness,
obstruction and shadow lists.

May import core.shared, core.lens and core.scene; never tiers, plans or Blender.
"""
