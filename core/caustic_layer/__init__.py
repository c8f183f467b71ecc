"""The caustic layer: the caustic of a glass lens as an emissive layer on its receivers.

May import core.shared, core.lens, core.scene, core.phase1 and core.tiers.

EEVEE can only render what a spot light can do; a real lens beam converges to a bright
core and then spreads in a halo. Here each secondary source (a light seen through a glass
sphere) is traced exactly as a structured grid of rays over the lens' lit disc
(:mod:`.beam_trace`), the rays are landed on the receivers' triangles
(:mod:`.receiver_bvh`), and the landed grid's flux is accumulated into one
non-overlapping irradiance raster per planar receiver patch (:mod:`.rasters`).
:mod:`.ray_budget` picks the ray count. Plain numpy; never imports bpy.
"""
