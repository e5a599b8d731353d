"""S1 and S2 of docs/results/peers.md in Blender's cloth: a 1 m square of
101 x 101 vertices, 0.1 kg/m^2, hanging from the two corners of its far
edge (S1, `fixtures/scenes/hang.toml`'s layout) or dropped from 10 cm over
a ball of radius 0.3 m (S2, `fixtures/scenes/drape-sphere.toml`'s), 2 s.

    /usr/bin/time -f "%U %S" blender -b --factory-startup -noaudio \
        --python tools/peers/blender_cloth.py -- --scene hang [--tension 0.2]

Blender's structural spring of rest length `L` has the stiffness
`tension / L`, so a square grid of spacing `a` has `E t = tension / a`
along its threads (shear springs add to it): `E t = 20 N/m` at `a = 1 cm`
is `tension = 0.2`; compression and shear take the same value. Everything
else is Blender 3.4's default cloth (5 steps a frame at 24 frames a
second, its damping, collision friction 5), except the vertex mass,
gravity, the collision distance (5 mm, the library's thickness), the
ball's outer thickness (1 mm), self-collision (off, as in the library's
scenes) and the air drag (none). Prints the frames, the wall seconds
spent stepping and the largest edge stretch at the end (over the run
with `--measure`), and for S2 the cloth's lowest point and how many
vertices are above the ball's centre.
"""

import argparse
import sys
import time

import bpy

ARGS = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
parser = argparse.ArgumentParser()
parser.add_argument("--scene", choices=["hang", "drape"], required=True)
parser.add_argument("--particles", type=int, default=101, help="vertices a side")
parser.add_argument("--tension", type=float, default=0.2, help="Blender's tension, compression and shear stiffness")
parser.add_argument("--quality", type=int, default=5, help="cloth steps a frame")
parser.add_argument("--fps", type=int, default=24)
parser.add_argument("--seconds", type=float, default=2.0)
parser.add_argument("--friction", type=float, default=5.0, help="Blender's cloth-collider friction")
parser.add_argument("--measure", action="store_true", help="the largest stretch over the run, not only at its end (slower)")
args = parser.parse_args(ARGS)

SIDE_M, DENSITY_KG_M2 = 1.0, 0.1

for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj, do_unlink=True)
scene = bpy.context.scene
scene.render.fps = args.fps
scene.gravity = (0.0, 0.0, -9.81)
frames = round(args.seconds * args.fps)
scene.frame_start, scene.frame_end = 1, frames + 1

# The grid: `particles` vertices a side (Blender 3.4 makes one more than
# its subdivisions).
height = 1.0 if args.scene == "hang" else 0.4
bpy.ops.mesh.primitive_grid_add(
    x_subdivisions=args.particles - 1, y_subdivisions=args.particles - 1, size=SIDE_M, location=(0.0, 0.0, height)
)
cloth_obj = bpy.context.active_object
mesh = cloth_obj.data
n = len(mesh.vertices)
if n != args.particles**2:
    sys.exit(f"grid has {n} vertices, expected {args.particles ** 2}")

mod = cloth_obj.modifiers.new("Cloth", "CLOTH")
s = mod.settings
s.quality = args.quality
s.mass = DENSITY_KG_M2 * SIDE_M * SIDE_M / n
s.tension_stiffness = s.compression_stiffness = s.shear_stiffness = args.tension
# Blender's air drag is a force against each vertex's velocity, whatever
# its mass: at 0.1 kg/m^2 its default (1) held the dropped cloth within
# 5 mm of where it started over 2 s.
s.air_damping = 0.0
mod.collision_settings.use_self_collision = False
mod.collision_settings.distance_min = 0.005

if args.scene == "hang":
    # The two corners of the far edge (largest y).
    far = [v.index for v in mesh.vertices if abs(v.co.y - SIDE_M / 2) < 1e-9 and abs(abs(v.co.x) - SIDE_M / 2) < 1e-9]
    if len(far) != 2:
        sys.exit(f"found {len(far)} far corners, expected 2")
    group = cloth_obj.vertex_groups.new(name="pins")
    group.add(far, 1.0, "REPLACE")
    s.vertex_group_mass = "pins"
else:
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, segments=64, ring_count=32, location=(0.0, 0.0, 0.0))
    ball = bpy.context.active_object
    ball.modifiers.new("Collision", "COLLISION")
    ball.collision.cloth_friction = args.friction
    ball.collision.thickness_outer = 0.001

depsgraph = bpy.context.evaluated_depsgraph_get()
rest = [(e.vertices[0], e.vertices[1], (mesh.vertices[e.vertices[0]].co - mesh.vertices[e.vertices[1]].co).length)
        for e in mesh.edges]
worst, stepping = 1.0, 0.0
for frame in range(1, frames + 2):
    start = time.perf_counter()
    scene.frame_set(frame)
    stepping += time.perf_counter() - start
    if args.measure or frame == frames + 1:
        x = [v.co.copy() for v in cloth_obj.evaluated_get(depsgraph).data.vertices]
        worst = max(worst, max((x[i] - x[j]).length / l for i, j, l in rest))
what = "peak stretch" if args.measure else "stretch at the end"
line = f"{args.scene}: {frames} frames, {args.quality} steps a frame, tension {args.tension}: stepping {stepping:.2f} s wall, {what} {worst:.3f}"
if args.scene == "drape":
    world = [cloth_obj.matrix_world @ p for p in x]
    line += f", lowest point z = {min(p.z for p in world):.3f} m, {sum(p.z > 0.0 for p in world)} of {n} vertices above the ball's centre"
print(line)
