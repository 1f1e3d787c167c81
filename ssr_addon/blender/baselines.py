"""The slides' baselines, set up as temporary scene changes so that the ordinary
EEVEE pass render shows them:

- cubemap: one reflection cubemap, an EEVEE sphere light probe, with ray tracing
  off: static (captured at one point for every surface), right for distant
  surroundings and for surfaces near the capture point, misplaced for nearby
  objects (parallax), and without self-reflection. Around a chosen object the
  probe's near clip lies outside the object, so it never sees itself.
  Otherwise (default_probe_placement) the probe goes where a level artist puts
  one: in free space over the middle of the scene at eye height. That is the
  horizontal centre of the rendered geometry's bounds at the camera's height,
  kept between the bottom and the top of the solid objects, moved out of any
  bounding box it lands in (sideways or up, whichever is nearer; a box around
  the camera is a room, not an obstacle). Slabs (floors, ceilings: far
  thinner than wide) do not count as solid: a mirror floor would pull the
  probe down to where every object smears across its reflection and a
  nearby one swells into a giant disc, and a probe above every object sees
  nothing but their tops. The influence sphere, which EEVEE also uses as the
  parallax sphere the reflection is projected onto, just encloses the solid
  objects: EEVEE keeps the parallax volume at least as big as the influence,
  so a sphere over all of a large floor would project nearby objects' images
  far away and swell them. Floor parts farther out get the world's
  reflection. The floor slabs are left out of the capture: a floor never
  reflects itself, and captured it would show up as a bright band in its own
  reflection.
- planar: the scene mirrored in one plane, an EEVEE plane light probe on a
  flat mesh. EEVEE uses plane probes only with screen-trace ray tracing, so
  that is switched on; other glossy surfaces then get EEVEE's own screen trace.
- none: the scene as it is (its world, light probes and ray tracing setting),
  exactly what `render --method none` renders. ssr: the same, rendered with
  the ray-tracing set-up SSR composites over (passes.SSR_BASE_RAYTRACING).

Everything goes through TemporaryChanges: the scene is as before on restore.
"""
import heapq
from dataclasses import dataclass

import bpy
from mathutils import Vector

from ..core.errors import SSRError

# The comparison modes a user picks (the SSR tab, `compare`), each the baseline of its name.
COMPARISON_MODES = (
    ("SSR", "SSR", "This add-on's screen-space reflections, falling back to the scene's own where rays miss"),
    ("CUBEMAP", "Cubemap", "One reflection cubemap (an EEVEE sphere probe): static, no self-reflection"),
    ("PLANAR", "Planar", "The scene mirrored in one plane (an EEVEE plane probe): exact on that plane only"),
    ("NONE", "None", "World and existing light probes only"),
)
BASELINES = tuple(mode.lower() for mode, _, _ in COMPARISON_MODES)

_GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT"}
_SLAB_THINNESS = 0.02  # a floor or ceiling slab's height relative to its width


def apply_baseline(scene, mode, changes, probe_object=None, mirror_object=None):
    """Change SCENE (through CHANGES) so that an EEVEE render shows baseline MODE.

    probe_object: the object the cubemap is captured around (default: default_probe_placement).
    mirror_object: the flat mesh of the planar mode (default: the largest flat mesh).
    """
    if mode not in BASELINES:
        raise SSRError(f"unknown comparison mode {mode!r}: expected one of {', '.join(BASELINES)}")
    _update_world_matrices(scene)
    if mode == "planar":
        _add_plane_probe(scene, changes, mirror_object or _largest_flat_mesh(scene))
        changes.set(scene.eevee, "use_raytracing", True)
        changes.set(scene.eevee, "ray_tracing_method", "SCREEN")
    elif mode == "cubemap":
        changes.set(scene.eevee, "use_raytracing", False)
        _add_sphere_probe(scene, changes, probe_object)


def _update_world_matrices(scene):
    """Objects' matrix_world as the render will see them: a scene just built by a script has
    stale ones (the last object added still reads as unscaled) until its depsgraph is evaluated."""
    next((layer for layer in scene.view_layers if layer.use), scene.view_layers[0]).update()


def rendered_geometry(scene):
    """The scene's objects that render as surfaces."""
    return [obj for obj in scene.objects if obj.type in _GEOMETRY_TYPES and not obj.hide_render]


def _world_bounds(objects):
    corners = [obj.matrix_world @ Vector(corner) for obj in objects for corner in obj.bound_box]
    return Vector(map(min, zip(*corners))), Vector(map(max, zip(*corners)))


def _new_probe(scene, changes, name, kind):
    data = bpy.data.lightprobes.new(name, kind)
    probe = bpy.data.objects.new(name, data)
    scene.collection.objects.link(probe)
    changes.on_restore(lambda: (bpy.data.objects.remove(probe), bpy.data.lightprobes.remove(data)))
    return probe


def _add_sphere_probe(scene, changes, centre_object):
    geometry = rendered_geometry(scene)
    if not geometry:
        raise SSRError(f"scene '{scene.name}' has no visible geometry for a reflection cubemap to capture")
    scene_low, scene_high = _world_bounds(geometry)
    if centre_object is not None:
        low, high = _world_bounds([centre_object])
        centre = (low + high) / 2
        # The near clip just outside the object: the cubemap holds everything but the object itself.
        clip_start = (high - low).length / 2 * 1.01 + 1e-3
        influence = None
    else:
        placement = default_probe_placement(scene, geometry)
        centre, influence = placement.location, placement.influence
        clip_start = (scene_high - scene_low).length * 1e-3 + 1e-3
        for floor in placement.floors:
            # A floor never reflects itself; captured, it would show up in its own reflection.
            changes.set(floor, "hide_probe_sphere", True)
    reach = max((Vector(corner) - centre).length for corner in _box_corners(scene_low, scene_high))
    probe = _new_probe(scene, changes, "SSR Cubemap", "SPHERE")
    probe.location = centre
    probe.data.influence_type = "ELIPSOID"
    # EEVEE's parallax sphere is the influence sphere; past its falloff band the whole scene,
    # or every solid object, is inside.
    probe.data.influence_distance = influence or reach * 1.25
    probe.data.clip_start = clip_start
    probe.data.clip_end = max(reach * 2.0, clip_start * 2.0)  # everything is captured


@dataclass
class ProbePlacement:
    location: Vector    # where the cubemap is captured
    influence: float    # radius of its influence and parallax sphere
    floors: list        # slabs at the bottom of the scene, left out of the capture


def default_probe_placement(scene, geometry=None):
    """Where the cubemap goes when no object is chosen: a ProbePlacement.

    Over the horizontal centre of the rendered geometry's bounds, at the camera's height
    kept within the heights of the solid objects (slabs left out), moved out of any bounding
    box it lands in. The sphere encloses every solid object past the influence's falloff band.
    """
    geometry = rendered_geometry(scene) if geometry is None else geometry
    scene_low, scene_high = _world_bounds(geometry)
    solid = [obj for obj in geometry if not _is_slab(obj)] or geometry
    low, high = _world_bounds(solid)
    camera = scene.camera.matrix_world.translation if scene.camera is not None else None
    height = (low.z + high.z) / 2 if camera is None else min(max(camera.z, low.z), high.z)
    wanted = Vector(((scene_low.x + scene_high.x) / 2, (scene_low.y + scene_high.y) / 2, height))
    # Bounding boxes around the camera are rooms (or domes) the camera looks from, not obstacles.
    obstacles = [obj for obj in geometry if camera is None or not _inside(camera, *_world_bounds([obj]))]
    furniture_low, furniture_high = _world_bounds([obj for obj in solid if obj in obstacles] or solid)
    margin = (furniture_high - furniture_low).length * 0.02 + 1e-3
    location = _free_point(wanted, [_world_bounds([obj]) for obj in obstacles], margin)
    reach = max((Vector(corner) - location).length for corner in _box_corners(low, high))
    floors = [obj for obj in geometry if _is_slab(obj) and _world_bounds([obj])[1].z <= low.z + margin
              and obj not in solid]
    return ProbePlacement(location, reach * 1.25, floors)


def _is_slab(obj):
    """A floor, ceiling or table top: its world bounds are far thinner vertically than across."""
    low, high = _world_bounds([obj])
    size = high - low
    return size.z <= _SLAB_THINNESS * max(size.x, size.y)


def _inside(point, low, high, margin=0.0):
    return all(lo - margin < p < hi + margin for p, lo, hi in zip(point, low, high))


def _free_point(wanted, boxes, margin):
    """The point nearest WANTED, found by stepping out of the boxes it is in (sideways or
    up, never down into the floor), that lies at least MARGIN outside every box."""
    queue, seen = [(0.0, tuple(wanted))], set()
    while queue and len(seen) < 1000:
        _, point = heapq.heappop(queue)
        if point in seen:
            continue
        seen.add(point)
        blocking = [box for box in boxes if _inside(point, *box, margin)]
        if not blocking:
            return Vector(point)
        for low, high in blocking:
            for axis, bound in ((0, low), (0, high), (1, low), (1, high), (2, high)):
                step = list(point)
                step[axis] = bound[axis] + (margin * 1.01 if bound is high else -margin * 1.01)
                heapq.heappush(queue, ((Vector(step) - wanted).length, tuple(step)))
    top = max(high.z for _, high in boxes)
    return Vector((wanted.x, wanted.y, top + margin * 1.01))  # above everything


def _box_corners(low, high):
    return [(x, y, z) for x in (low.x, high.x) for y in (low.y, high.y) for z in (low.z, high.z)]


def _flat_extent(obj):
    """Half sizes (x, y) of a mesh flat along its local Z axis (a plane, or a slab: a floor of
    some thickness), in its local units, or None."""
    if obj.type != "MESH":
        return None
    low, high = Vector(map(min, zip(*obj.bound_box))), Vector(map(max, zip(*obj.bound_box)))
    size = high - low
    scaled = Vector(abs(length * scale) for length, scale in zip(size, obj.matrix_world.to_scale()))
    if size.x <= 0 or size.y <= 0 or scaled.z > _SLAB_THINNESS * max(scaled.x, scaled.y):
        return None
    return size.x / 2, size.y / 2


def _largest_flat_mesh(scene):
    def world_area(obj):
        half_x, half_y = _flat_extent(obj)
        scale = obj.matrix_world.to_scale()
        return half_x * abs(scale.x) * half_y * abs(scale.y)
    flat = [obj for obj in rendered_geometry(scene) if _flat_extent(obj) is not None]
    if not flat:
        raise SSRError(f"scene '{scene.name}' has no flat mesh for the planar mode: "
                       "choose a mirror plane in the SSR tab")
    return max(flat, key=world_area)


def _add_plane_probe(scene, changes, mirror):
    extent = _flat_extent(mirror)
    if extent is None:
        raise SSRError(f"'{mirror.name}' is not a flat mesh (flat along its local Z axis), "
                       "so the planar mode cannot mirror the scene in it")
    _, rotation, scale = mirror.matrix_world.decompose()
    low = Vector(map(min, zip(*mirror.bound_box)))
    high = Vector(map(max, zip(*mirror.bound_box)))
    probe = _new_probe(scene, changes, "SSR Mirror Plane", "PLANE")
    centre = (low + high) / 2
    # On a slab, the face towards the camera (its top, for a floor) is the mirror.
    camera_z = (mirror.matrix_world.inverted() @ scene.camera.matrix_world.translation).z
    centre.z = high.z if camera_z >= centre.z else low.z
    probe.location = mirror.matrix_world @ centre
    probe.rotation_mode = "QUATERNION"
    probe.rotation_quaternion = rotation
    # The probe spans the mirror; a unit Z scale keeps its influence distance in scene units.
    probe.scale = (extent[0] * abs(scale.x), extent[1] * abs(scale.y), 1.0)
    # Otherwise the capture, taken from just below the plane, sees the mirror's underside.
    changes.set(mirror, "hide_probe_plane", True)
