"""Planning: which secondary sources get a lens light (flux budget, cut-off, cap, merging),
receivers behind a lens, Cycles' own caustics to turn off.

May import core.shared, core.lens, core.scene, core.phase1, core.tiers.
"""
