"""Plain-Python 3-vectors for the tests' independent expectations.

On purpose not numpy: the expected values must not share the code's numpy path.
"""

import math


def vsub(a, b):
    return tuple(x - y for x, y in zip(a, b, strict=False))


def vadd(a, b):
    return tuple(x + y for x, y in zip(a, b, strict=False))


def vscale(a, s):
    return tuple(x * s for x in a)


def vdot(a, b):
    return sum(x * y for x, y in zip(a, b, strict=False))


def vcross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def vnorm(a):
    return math.sqrt(vdot(a, a))


def vunit(a):
    return vscale(a, 1.0 / vnorm(a))
