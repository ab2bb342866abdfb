"""Run inside Blender (``blender -b --factory-startup --python blender_fbx.py -- ...``), never imported by dancekit.

Two jobs, named by the first argument after ``--``:

``export IN.glb OUT.fbx FPS_NUM FPS_DEN``
    Import the glb (dancekit's rig as an armature, the skinned mannequin, the animation "dance") at the scene
    frame rate ``FPS_NUM / FPS_DEN`` and export it as FBX with Blender's own exporter: the armature and the
    mesh, the animation baked at every frame (no key reduction), no leaf bones.

``read IN.fbx OUT.npz``
    Import an FBX and write, for every frame of its animation, the world position of every bone's head:
    ``names`` (J,), ``positions`` (T, J, 3) in metres with y up (glTF's axes: Blender's (x, y, z) is
    (x, -z, y) there) and ``fps``.

Blender's own messages go to stdout; the caller keeps them unless the job fails.
"""

import sys


def _numpy_compat():
    """Blender 3.4's glTF importer (Debian 12's blender) still spells ``np.bool``, which NumPy 1.24 removed
    (NumPy 2 has it again); give it the alias it means."""
    import numpy as np

    if "bool" not in np.__dict__:
        np.bool = bool


def _reset(fps_num=None, fps_den=None):
    import bpy

    _numpy_compat()

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    if fps_num is not None:
        scene.render.fps = int(fps_num)
        scene.render.fps_base = float(fps_den)
    return scene


def _frame_range(scene):
    """The first and last frame of the animations in the scene (actions of every object)."""
    import bpy

    ranges = [tuple(a.frame_range) for a in bpy.data.actions]
    if not ranges:
        raise RuntimeError("no animation in the file")
    return int(round(min(r[0] for r in ranges))), int(round(max(r[1] for r in ranges)))


def export(src, dst, fps_num, fps_den):
    import bpy

    scene = _reset(fps_num, fps_den)
    bpy.ops.import_scene.gltf(filepath=src)
    first, last = _frame_range(scene)
    scene.frame_start, scene.frame_end = first, last
    bpy.ops.export_scene.fbx(
        filepath=dst, use_selection=False, object_types={"ARMATURE", "MESH", "EMPTY"},
        add_leaf_bones=False, use_armature_deform_only=False, apply_unit_scale=True,
        bake_anim=True, bake_anim_use_all_bones=True, bake_anim_use_nla_strips=False,
        bake_anim_use_all_actions=False, bake_anim_force_startend_keying=True,
        bake_anim_step=1.0, bake_anim_simplify_factor=0.0, path_mode="AUTO")


def read(src, dst):
    import bpy
    import numpy as np

    scene = _reset()
    bpy.ops.import_scene.fbx(filepath=src, automatic_bone_orientation=False, ignore_leaf_bones=False)
    arms = [o for o in scene.objects if o.type == "ARMATURE"]
    if len(arms) != 1:
        raise RuntimeError(f"expected one armature, found {len(arms)}")
    arm = arms[0]
    first, last = _frame_range(scene)
    names = [b.name for b in arm.pose.bones]
    out = np.zeros((last - first + 1, len(names), 3))
    for k, f in enumerate(range(first, last + 1)):
        scene.frame_set(f)
        for j, b in enumerate(arm.pose.bones):
            p = arm.matrix_world @ b.head
            out[k, j] = (p.x, p.z, -p.y)  # Blender z up -> y up
    np.savez(dst, names=np.array(names), positions=out, fps=scene.render.fps / scene.render.fps_base,
             first_frame=first)


def main(argv):
    args = argv[argv.index("--") + 1:] if "--" in argv else []
    if args[:1] == ["export"] and len(args) == 5:
        export(args[1], args[2], args[3], args[4])
    elif args[:1] == ["read"] and len(args) == 3:
        read(args[1], args[2])
    else:
        raise SystemExit(f"usage: blender -b --python {__file__} -- export IN.glb OUT.fbx FPS_NUM FPS_DEN | "
                         "read IN.fbx OUT.npz")


if __name__ == "__main__":
    main(sys.argv)
