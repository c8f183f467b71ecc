"""What the user reads: the run's report text and the panel's short texts.

May import core.shared, core.lens, core.scene, core.phase1 (skip reasons) and core.tiers.
"""
