"""What the user reads: the run's report text and the panel's short texts.

May import core.phase1 (skip reasons) and below.
"""
