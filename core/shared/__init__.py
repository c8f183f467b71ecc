"""Small tools every core package may use: threads over row blocks, ranges, a cross
product of row arrays (`vectors`), a share in words (`words`).

Imports numpy only; nothing else of the core.
"""
