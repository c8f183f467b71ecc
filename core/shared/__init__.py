"""Small numeric tools every core package may use: threads over row blocks, ranges.

Imports numpy only; nothing else of the core.
"""
