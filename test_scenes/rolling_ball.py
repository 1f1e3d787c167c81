"""A ball rolling across a dark glossy floor in front of a static camera.

The red ball moves 0.35 units a frame in x over frames 1-8 (and turns as it
rolls) above a dark, nearly mirror-like metal floor, so its reflection moves
with it: where the ball and its reflection were, the temporal history holds
stale reflections that the filter must drop, while the reflections of the
static backdrop and boxes must stay steady.
"""
from _common import add_camera, add_mesh, add_sun, animate_location, principled, set_render, set_world

BALL_RADIUS = 0.5
STEP = 0.35
FIRST_X = -1.25


def build(scene):
    set_render(scene, 320, 180)
    set_world(scene, (0.2, 0.25, 0.35), strength=0.6)
    add_mesh(scene, "plane", "Floor", (0, 0, 0), 12.0,
             principled("DarkGloss", base_color=(0.15, 0.15, 0.15), roughness=0.05, metallic=1.0))
    add_mesh(scene, "cube", "Backdrop", (0.0, 4.0, 1.5), (4.0, 0.1, 1.5),
             principled("Backdrop", base_color=(0.7, 0.7, 0.65), roughness=0.8))
    for name, color, location, size in (("Blue", (0.05, 0.15, 0.85), (-2.4, 3.2, 0.5), (0.5, 0.5, 0.5)),
                                        ("Green", (0.05, 0.7, 0.1), (0.0, 3.4, 0.7), (0.4, 0.4, 0.7)),
                                        ("Yellow", (0.9, 0.7, 0.05), (2.3, 3.1, 0.4), (0.6, 0.4, 0.4))):
        add_mesh(scene, "cube", f"Box{name}", location, size,
                 principled(name, base_color=color, roughness=0.6))
    ball = add_mesh(scene, "uv_sphere", "Ball", (FIRST_X, 1.0, BALL_RADIUS), BALL_RADIUS,
                    principled("Ball", base_color=(0.9, 0.2, 0.03), roughness=0.5),
                    segments=32, ring_count=16)
    # Rolling without slipping: turn about y by distance / radius each frame.
    for frame in range(8):
        ball.rotation_euler = (0.0, frame * STEP / BALL_RADIUS, 0.0)
        ball.keyframe_insert("rotation_euler", frame=1 + frame)
    animate_location(scene, ball, [(FIRST_X + STEP * frame, 1.0, BALL_RADIUS) for frame in range(8)])
    add_sun(scene, (50, 0, 200), strength=3.0)
    add_camera(scene, (0.0, -5.5, 1.8), (0.0, 1.5, 0.4), lens=38.0)
