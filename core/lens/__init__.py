"""Lenses: the lens interface and its kinds (one file each, registered in `kinds`), the ball's
exact optics and cap geometry, refraction and Fresnel, glass materials.

May import core.shared; nothing above it (scene, phase1, tiers … import lens, never the
reverse).
"""
