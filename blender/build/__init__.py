"""What Generate and Bake make in the scene, one floor per module (each imports only those
listed before it):

* `marks`: the mark on everything the extension creates and the names it gives (no bpy);
* `ownership`: which marked objects are still the extension's, which the user's (kept);
* `mask_nodes`: an Exact profile light's shadow mask; `lights`: the lens lights, their
  linking collections, profile images and node trees; `layers`: the caustic layers;
  `baked_layers`: the baked layers' meshes, atlas images and materials;
  `cycles_caustics`: Cycles' own caustics of the lenses, off and back on;
* `cleanup`: Clear, above every builder (it knows what each one leaves).

May import core and blender.read; never commands or ui.
"""
