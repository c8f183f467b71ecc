"""Animation: the bake's keyed light tracks and profile slices, the caustic layer's time
segments, the keys that match a light across frames.

May import every core package but report and bi.
"""
