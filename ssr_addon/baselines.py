"""The slides' baselines, set up as temporary scene changes so that the ordinary
EEVEE pass render shows them:

- cubemap: one reflection cubemap, an EEVEE sphere light probe around a chosen
  object (or the centre of the scene), with ray tracing off. Static (captured
  at one point for every surface) and without self-reflection: the probe's
  near clip lies outside the chosen object, so it never sees itself.
- planar: the scene mirrored in one plane, an EEVEE plane light probe on a
  flat mesh. EEVEE uses plane probes only with screen-trace ray tracing, so
  that is switched on; other glossy surfaces then get EEVEE's own screen trace.
- none: the scene as it is (its world, light probes and ray tracing setting),
  exactly what `render --method none` renders. ssr: the same, rendered with
  the ray-tracing set-up SSR composites over (passes.SSR_BASE_RAYTRACING).

Everything goes through TemporaryChanges: the scene is as before on restore.
"""
import bpy
from mathutils import Vector

from .errors import SSRError

BASELINES = ("ssr", "cubemap", "planar", "none")

_GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT"}
_FLATNESS = 1e-4  # a plane's thickness relative to its size


def apply_baseline(scene, mode, changes, probe_object=None, mirror_object=None):
    """Change SCENE (through CHANGES) so that an EEVEE render shows baseline MODE.

    probe_object: the object the cubemap is captured around (default: the scene's centre).
    mirror_object: the flat mesh of the planar mode (default: the largest flat mesh).
    """
    if mode not in BASELINES:
        raise SSRError(f"unknown comparison mode {mode!r}: expected one of {', '.join(BASELINES)}")
    if mode == "planar":
        _add_plane_probe(scene, changes, mirror_object or _largest_flat_mesh(scene))
        changes.set(scene.eevee, "use_raytracing", True)
        changes.set(scene.eevee, "ray_tracing_method", "SCREEN")
    elif mode == "cubemap":
        changes.set(scene.eevee, "use_raytracing", False)
        _add_sphere_probe(scene, changes, probe_object)


def _rendered_geometry(scene):
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
    geometry = _rendered_geometry(scene)
    if not geometry:
        raise SSRError(f"scene '{scene.name}' has no visible geometry for a reflection cubemap to capture")
    scene_low, scene_high = _world_bounds(geometry)
    if centre_object is not None:
        low, high = _world_bounds([centre_object])
        centre = (low + high) / 2
        # The near clip just outside the object: the cubemap holds everything but the object itself.
        clip_start = (high - low).length / 2 * 1.01 + 1e-3
    else:
        centre = (scene_low + scene_high) / 2
        clip_start = (scene_high - scene_low).length * 1e-3 + 1e-3
    reach = max((Vector(corner) - centre).length for corner in _box_corners(scene_low, scene_high))
    probe = _new_probe(scene, changes, "SSR Cubemap", "SPHERE")
    probe.location = centre
    probe.data.influence_type = "ELIPSOID"
    probe.data.influence_distance = reach * 1.25  # past the falloff band, so the whole scene is inside
    probe.data.clip_start = clip_start
    probe.data.clip_end = max(reach * 2.0, clip_start * 2.0)


def _box_corners(low, high):
    return [(x, y, z) for x in (low.x, high.x) for y in (low.y, high.y) for z in (low.z, high.z)]


def _flat_extent(obj):
    """Half sizes (x, y) of a mesh flat along its local Z axis, in its local units, or None."""
    if obj.type != "MESH":
        return None
    low, high = Vector(map(min, zip(*obj.bound_box))), Vector(map(max, zip(*obj.bound_box)))
    size = high - low
    if size.x <= 0 or size.y <= 0 or size.z > _FLATNESS * max(size.x, size.y):
        return None
    return size.x / 2, size.y / 2


def _largest_flat_mesh(scene):
    def world_area(obj):
        half_x, half_y = _flat_extent(obj)
        scale = obj.matrix_world.to_scale()
        return half_x * abs(scale.x) * half_y * abs(scale.y)
    flat = [obj for obj in _rendered_geometry(scene) if _flat_extent(obj) is not None]
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
    probe.location = mirror.matrix_world @ ((low + high) / 2)
    probe.rotation_mode = "QUATERNION"
    probe.rotation_quaternion = rotation
    # The probe spans the mirror; a unit Z scale keeps its influence distance in scene units.
    probe.scale = (extent[0] * abs(scale.x), extent[1] * abs(scale.y), 1.0)
    # Otherwise the capture, taken from just below the plane, sees the mirror's underside.
    changes.set(mirror, "hide_probe_plane", True)
