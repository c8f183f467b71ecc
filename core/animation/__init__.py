"""Animation: the bake's keyed light tracks and profile slices, the caustic layer's time
segments, the keys that match a light across frames, what a bake was baked from
(`bake_inputs`).

May import every core package but report and bi.
"""
