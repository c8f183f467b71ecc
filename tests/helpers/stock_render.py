"""Render a saved .blend in a fresh Blender process that never loads the extension (as
a render-farm node running `blender -b file.blend -a` does): the baked keys alone
drive the lens lights. Shared by the bake's render tests."""

import json
import os
import subprocess
import sys
import textwrap

import numpy as np

#: Rendered by a process that only opens the file: no extension anywhere. Renders
#: frame argv[3] as an animation of one frame, then that frame again with the
#: "Lens Lights" collection hidden.
STOCK_RENDER = textwrap.dedent(
    """
    import json, os, sys
    import bpy
    path, out = sys.argv[1], sys.argv[2]
    bpy.ops.wm.open_mainfile(filepath=path)
    scene = bpy.context.scene
    facts = dict(
        registered=scene.bl_rna.properties.get("lens_lights") is not None,
        operators=hasattr(bpy.types, "LENS_LIGHTS_OT_generate"),
    )
    frame = int(sys.argv[3])
    scene.frame_start = scene.frame_end = frame
    scene.render.filepath = os.path.join(out, "baked_####")
    bpy.ops.render.render(animation=True)  # what `blender -b file.blend -a` runs
    bpy.data.collections["Lens Lights"].hide_render = True
    scene.render.filepath = os.path.join(out, "without.exr")
    bpy.ops.render.render(write_still=True)
    print("FACTS " + json.dumps(facts), flush=True)
    sys.stdout.flush()
    os._exit(0)
    """
)


def load(path):
    """The mean of an image's RGB channels per pixel (rows from the bottom)."""
    import bpy

    img = bpy.data.images.load(str(path))
    px = np.array(img.pixels[:], dtype=float).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px[..., :3].mean(axis=2)


def stock_render(blend, tmp, frame, timeout=600):
    """Render `frame` of `blend` in a new process without the extension: (facts,
    with the lens lights, without them)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run(
        [sys.executable, "-c", STOCK_RENDER, str(blend), str(tmp), str(frame)],
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
    )
    facts = [ln for ln in run.stdout.splitlines() if ln.startswith("FACTS ")]
    assert facts, run.stdout[-2000:] + run.stderr[-2000:]
    return json.loads(facts[0][6:]), load(tmp / f"baked_{frame:04d}.exr"), load(tmp / "without.exr")
