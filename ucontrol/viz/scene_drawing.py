"""The meshcat drawing of a scene: robot, surfaces, contact points, force arrows, phase label.

Everything is drawn under the meshcat node ``ucontrol`` in the scene's world coordinates; that
node turns the world so that the scene's "up" (opposite to gravity) is meshcat's vertical and
moves the centre of the view to meshcat's origin, around which the camera orbits. The
robot is its URDF visual geometry (meshes and primitives, loaded by Pinocchio's meshcat
visualizer), completed by simple shapes where the URDF has none: a sphere at each joint whose
body has no visual and a cylinder from it to each joint and frame it carries. Each contact gets a
marker at its contact point (the point of its sphere nearest to the surface) and an arrow along
the surface normal whose length is proportional to the normal contact force, impulse / dt.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import coal
import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
from meshcat.animation import AnimationFrameVisualizer
from numpy.typing import NDArray
from pinocchio.visualize import MeshcatVisualizer

from ucontrol.control.phase import Phase
from ucontrol.exceptions import InvalidParameterError
from ucontrol.scene import Scene
from ucontrol.viz.phase_colours import PHASE_COLOURS

#: Colour (RGBA in [0, 1]) of robot primitives that have no colour in the URDF, and of the
#: shapes drawn for bodies without visual geometry.
ROBOT_COLOUR = (0.95, 0.45, 0.05, 1.0)
#: Colour Pinocchio gives to URDF visuals without a material.
_URDF_DEFAULT_COLOUR = (0.9, 0.9, 0.9, 1.0)
#: Colour (hex RGB) of the surfaces, drawn translucent.
SURFACE_COLOUR = 0x8C8C8C
#: Colour (hex RGB) of the contact-point markers.
CONTACT_COLOUR = 0x7B2CBF
#: Colour (hex RGB) of the force arrows.
ARROW_COLOUR = 0x1F9E3A
#: Longest force arrow, as a fraction of the radius of the view.
MAX_ARROW = 1.0
#: Length of the arrow of a force equal to the robot's weight (default scale), as a fraction
#: of the radius of the view.
WEIGHT_ARROW = 0.5
#: Vertical field of view of meshcat's default camera in [deg].
CAMERA_FOV = 75.0
#: Root node of the drawing in the meshcat tree.
ROOT = "ucontrol"
#: Scale that hides a node (meshcat animations cannot toggle visibility).
_HIDDEN = 1e-6
#: Largest number of configurations used to frame the view.
_FRAMING_SAMPLES = 200

Matrix = NDArray[np.float64]
Vector = NDArray[np.float64]


class SceneDrawing:
    """A scene drawn in a meshcat viewer, placed at any configuration by :meth:`place`.

    Args:
        scene: The scene (robot, contacts and their surfaces).
        viewer: The meshcat viewer to draw in; the node ``ucontrol`` is replaced.
        configurations: Configurations the view must frame, shape (K, nq); default the scene's
            initial configuration. A replay passes the run's configurations.
        force_scale: Arrow length per unit of contact force in [m/N]; default: the robot's
            weight (its total mass times 9.81 m/s² when it has no gravity) is half the
            radius of the view (:data:`WEIGHT_ARROW`). Arrows are at most that radius long.
        phases: Draw the label of the controller's phase (a run of the phase machine).
        robot_colour: RGBA in [0, 1] of robot primitives without a URDF colour.

    Attributes:
        up_rotation: Rotation from the scene's world to meshcat's (scene up -> meshcat z),
            shape (3, 3).
        centre: Centre of the view in the scene's world in [m], shape (3,). A world point p
            is drawn at ``up_rotation @ (p - centre)`` in meshcat's world.
        radius: Radius of the view in [m].
        camera_position: Camera position in meshcat's world in [m], shape (3,); the camera
            looks at meshcat's origin with meshcat's z up.
        force_scale: Arrow length per unit of contact force in [m/N].

    Raises:
        InvalidParameterError: ``configurations`` is not of shape (K, nq) or ``force_scale``
            is not positive.
    """

    def __init__(
        self,
        scene: Scene,
        viewer: meshcat.Visualizer,
        *,
        configurations: NDArray[np.float64] | None = None,
        force_scale: float | None = None,
        phases: bool = False,
        robot_colour: Sequence[float] = ROBOT_COLOUR,
    ) -> None:
        robot = scene.robot
        self._model = robot.model
        self._data = pin.Data(robot.model)
        self._contacts = [
            (robot.frame_id(c.frame), c.surface.normal, c.radius) for c in scene.contacts
        ]
        self.up_rotation = _up_rotation(robot.gravity)
        samples = _configurations(configurations, scene.q0, robot.nq)
        points = self._points(samples)
        self.centre, self.radius = _bounds(points, [c.radius for c in scene.contacts])
        self.force_scale = _force_scale(force_scale, robot.model, robot.gravity, self.radius)
        direction = _view_direction(points @ self.up_rotation.T)
        distance = 1.1 * self.radius / np.sin(np.radians(CAMERA_FOV / 2))  # [m]
        self.camera_position = distance * direction

        self._geometry = _visual_geometry(scene, tuple(robot_colour))
        self._geometry_data = pin.GeometryData(self._geometry)
        # The view first: a browser receives the scene in this order, the meshes last.
        _set_camera(viewer, self.camera_position)
        viewer["/Axes"].set_property("visible", False)  # meshcat's origin is the view centre
        if scene.contacts:
            viewer["/Grid"].set_property("visible", False)  # the surfaces are drawn
        root = viewer[ROOT]
        root.delete()
        root.set_transform(_pose(self.up_rotation, -self.up_rotation @ self.centre))
        self._moving: dict[str, tuple[Vector, Matrix, Any]] = {}
        #: Moving environment shapes: pose at x = 0 (4, 4), scale (3,) or None, motion.
        self._moving_shapes: dict[str, tuple[Matrix, Vector | None, Any]] = {}
        self._draw_surfaces(root, scene)
        self._draw_shapes(root, scene)
        self._draw_contacts(root)
        self._labels = _draw_labels(root, self, direction) if phases else {}
        visualizer = MeshcatVisualizer(self._model, None, self._geometry)
        visualizer.initViewer(viewer=root)
        visualizer.loadViewerModel(rootNodeName="robot")
        self._visual_nodes = [
            visualizer.getViewerNodeName(obj, pin.GeometryType.VISUAL)
            for obj in self._geometry.geometryObjects
        ]
        self.place(viewer, scene.q0, np.zeros(len(scene.contacts)), Phase.FREE, t=0.0)

    def place(
        self,
        target: meshcat.Visualizer | AnimationFrameVisualizer,
        q: Vector,
        force: Vector,
        phase: Phase | int | None = None,
        t: float | None = None,
    ) -> None:
        """Draw the robot at ``q`` with the contact forces ``force`` and the phase ``phase``.

        Moving surfaces and environment shapes are drawn where they are at time ``t`` [s]
        (not moved when None).

        Args:
            target: The viewer (live drawing) or one frame of a meshcat animation of it
                (``animation.at_frame(viewer, k)``).
            q: Configuration, shape (nq,).
            force: Normal force of each constraint in [N], shape (n,) with contacts first
                (stops are not drawn); e.g. impulse / dt.
            phase: Phase of the controller; None or ignored without ``phases``.
            t: Time in [s] at which moving surfaces are drawn; None leaves them in place.
        """
        model, data = self._model, self._data
        pin.framesForwardKinematics(model, data, q)
        pin.updateGeometryPlacements(model, data, self._geometry, self._geometry_data)
        for i, obj in enumerate(self._geometry.geometryObjects):
            scale = obj.meshScale if not np.allclose(obj.meshScale, 1.0) else None
            oMg = self._geometry_data.oMg[i]
            _place(target[f"{ROOT}/{self._visual_nodes[i]}"], oMg.homogeneous, scale)
        for i, (frame_id, normal, radius) in enumerate(self._contacts):
            point = data.oMf[frame_id].translation - radius * normal  # [m]
            rotation = _rotation_y_to(normal)
            _place(target[f"{ROOT}/contacts/{i}/point"], _pose(np.eye(3), point))
            length = min(self.force_scale * max(float(force[i]), 0.0), MAX_ARROW * self.radius)
            shown = length > 1e-9 * self.radius
            _place(
                target[f"{ROOT}/contacts/{i}/arrow"],
                _pose(rotation, point),
                (1.0, length if shown else _HIDDEN, 1.0),
            )
            head = 1.0 if shown else _HIDDEN
            _place(
                target[f"{ROOT}/contacts/{i}/head"],
                _pose(rotation, point + length * normal),
                (head, head, head),
            )
        if t is not None:
            for name, (foot, rotation, motion) in self._moving.items():
                displacement = motion(t)[0]  # [m]
                _place(target[f"{ROOT}/surfaces/{name}"], _pose(rotation, foot + displacement))
            for name, (pose, scale, motion) in self._moving_shapes.items():
                moved = pose.copy()
                moved[:3, 3] += motion(t)[0]  # [m]
                _place(target[f"{ROOT}/shapes/{name}"], moved, scale)
        for label, pose in self._labels.items():
            size = 1.0 if phase is not None and int(phase) == label else _HIDDEN
            _place(target[f"{ROOT}/phase/{label.name.lower()}"], pose, (size, size, size))

    def _points(self, configurations: Matrix) -> Matrix:
        """World positions of the joints, frames and contact points at ``configurations``."""
        model, data = self._model, self._data
        step = max(1, len(configurations) // _FRAMING_SAMPLES)
        points: list[Vector] = []
        for q in configurations[::step]:
            pin.framesForwardKinematics(model, data, q)
            points.extend(data.oMi[j].translation.copy() for j in range(1, model.njoints))
            points.extend(data.oMf[f].translation.copy() for f in range(1, model.nframes))
            points.extend(
                data.oMf[frame_id].translation - radius * normal
                for frame_id, normal, radius in self._contacts
            )
        return np.array(points).reshape(-1, 3)

    def _draw_surfaces(self, root: meshcat.Visualizer, scene: Scene) -> None:
        """Each plane as a thin box whose top face is the plane, centred below the view."""
        planes = {contact.surface.name: contact.surface for contact in scene.contacts}
        side, thickness = 2.4 * self.radius, 0.02 * self.radius  # [m]
        material = mg.MeshPhongMaterial(color=SURFACE_COLOUR, opacity=0.6)
        for name, plane in planes.items():
            normal = plane.normal
            foot = self.centre - normal * (normal @ (self.centre - plane.point))
            node = root[f"surfaces/{name}"]
            node.set_object(mg.Box([side, side, thickness]), material)
            node.set_transform(_pose(_rotation_z_to(normal), foot - 0.5 * thickness * normal))
            if plane.motion is not None:
                self._moving[name] = (
                    foot - 0.5 * thickness * normal,
                    _rotation_z_to(normal),
                    plane.motion,
                )

    def _draw_shapes(self, root: meshcat.Visualizer, scene: Scene) -> None:
        """The environment shapes of the scene's collision pairs (halfspaces as planes).

        A mesh is drawn from its file (OBJ, STL or DAE through meshcat; any other format coal
        reads as its convex hull) with the shape's placement and scale. A shape with a
        motion is recorded so that :meth:`place` translates it by x(t).
        """
        material = mg.MeshPhongMaterial(color=SURFACE_COLOUR, opacity=0.6)
        side, thickness = 2.4 * self.radius, 0.02 * self.radius  # [m]
        shapes = {
            pair.other.name: pair.other
            for pair in scene.collision_pairs
            if not isinstance(pair.other, str)
        }
        for name, shape in shapes.items():
            node = root[f"shapes/{name}"]
            scale: Vector | None = None
            if shape.type == "halfspace":
                normal = shape.normal
                foot = self.centre - normal * (normal @ (self.centre - shape.position))
                node.set_object(mg.Box([side, side, thickness]), material)
                pose = _pose(_rotation_z_to(normal), foot - 0.5 * thickness * normal)
            elif shape.type == "box":
                node.set_object(mg.Box(list(shape.size)), material)
                pose = shape.placement.homogeneous
            elif shape.type == "mesh":
                geometry, scaled = _mesh_geometry(shape)
                node.set_object(geometry, material)
                pose = shape.placement.homogeneous
                scale = None if scaled else np.asarray(shape.scale, dtype=float)
            else:
                node.set_object(mg.Sphere(shape.radius), material)
                pose = _pose(np.eye(3), shape.position)
            _place(node, pose, scale)
            if shape.motion is not None:
                self._moving_shapes[name] = (pose, scale, shape.motion)

    def _draw_contacts(self, root: meshcat.Visualizer) -> None:
        """A marker, an arrow shaft of unit length and an arrow head per contact."""
        r = self.radius
        marker = mg.MeshPhongMaterial(color=CONTACT_COLOUR)
        arrow = mg.MeshPhongMaterial(color=ARROW_COLOUR)
        for i in range(len(self._contacts)):
            root[f"contacts/{i}/point"].set_object(mg.Sphere(0.05 * r), marker)
            shaft = root[f"contacts/{i}/arrow/shaft"]
            shaft.set_object(mg.Cylinder(1.0, 0.012 * r), arrow)  # along y, unit length
            shaft.set_transform(_pose(np.eye(3), np.array([0.0, 0.5, 0.0])))
            cone = root[f"contacts/{i}/head/cone"]
            cone.set_object(mg.Cylinder(0.08 * r, radiusTop=0.0, radiusBottom=0.03 * r), arrow)
            cone.set_transform(_pose(np.eye(3), np.array([0.0, 0.04 * r, 0.0])))


class _TextTexture(mg.Texture):
    """Text drawn by the viewer on a 256 x 256 canvas (meshcat's ``_text`` texture)."""

    def __init__(self, text: str, font_size: int = 40) -> None:
        super().__init__()
        self.text = text
        self.font_size = font_size

    def lower(self, object_data: Any) -> dict[str, Any]:
        return {
            "uuid": self.uuid,
            "type": "_text",
            "text": self.text,
            "font_size": self.font_size,
            "font_face": "sans-serif",
        }


class _PlaneGeometry(mg.Geometry):
    """A rectangle in its local xy-plane, facing +z (three.js ``PlaneGeometry``)."""

    def __init__(self, width: float, height: float) -> None:
        super().__init__()
        self.width = width
        self.height = height

    def lower(self, object_data: Any) -> dict[str, Any]:
        return {
            "uuid": self.uuid,
            "type": "PlaneGeometry",
            "width": self.width,
            "height": self.height,
        }


def _draw_labels(
    root: meshcat.Visualizer, drawing: SceneDrawing, direction: Vector
) -> dict[Phase, Matrix]:
    """One label per phase at the top left of the view, facing the camera; returns their poses.

    The label sits outside the sphere of the view, so it never hides the robot.
    """
    r = drawing.radius
    up = np.array([0.0, 0.0, 1.0]) - direction[2] * direction
    up /= np.linalg.norm(up)
    right = np.cross(up, direction)
    rotation_viewer = np.column_stack([right, up, direction])
    offset = r * (1.2 * up - 1.0 * right)  # [m] in meshcat's world
    position = drawing.centre + drawing.up_rotation.T @ offset  # [m] in the scene's world
    pose = _pose(drawing.up_rotation.T @ rotation_viewer, position)
    width = 0.7 * r  # [m]
    poses = {}
    for phase in Phase:
        node = root[f"phase/{phase.name.lower()}"]
        colour = int(PHASE_COLOURS[phase].lstrip("#"), 16)
        node["back"].set_object(
            mg.Box([width, 0.2 * width, 0.01 * width]), mg.MeshBasicMaterial(color=colour)
        )
        node["back"].set_transform(_pose(np.eye(3), np.array([0.0, 0.03 * width, -0.01 * width])))
        node["text"].set_object(
            _PlaneGeometry(width, width),
            mg.MeshBasicMaterial(map=_TextTexture(phase.name.lower()), transparent=True),
        )
        poses[phase] = pose
    return poses


def _place(
    node: meshcat.Visualizer | AnimationFrameVisualizer,
    pose: Matrix,
    scale: Sequence[float] | NDArray[np.float64] | None = None,
) -> None:
    """Set the pose (4, 4) and optional scale (3,) of a live node or of an animation frame."""
    if isinstance(node, AnimationFrameVisualizer):
        node.set_transform(pose)  # position and orientation tracks
        if scale is not None:
            node.set_property("scale", "vector3", [float(s) for s in scale])
        return
    if scale is not None:
        pose = pose.copy()
        pose[:3, :3] = pose[:3, :3] * np.asarray(scale, dtype=float)  # scales the columns
    node.set_transform(pose)


def _mesh_geometry(shape: Any) -> tuple[Any, bool]:
    """The meshcat geometry of a mesh environment shape, and whether it is already scaled.

    OBJ, STL and DAE files are sent as they are (meshcat scales them through the node);
    another format coal reads is drawn as its convex hull, scaled, as the contact sees it.
    """
    path = Path(shape.mesh)
    loaders = {
        ".obj": mg.ObjMeshGeometry,
        ".stl": mg.StlMeshGeometry,
        ".dae": mg.DaeMeshGeometry,
    }
    loader = loaders.get(path.suffix.lower())
    if loader is not None:
        return loader.from_file(str(path)), False
    from scipy.spatial import ConvexHull

    from ucontrol.contact.collision_geometry import load_mesh_hull  # loads coal

    points = np.asarray(load_mesh_hull(str(path), shape.scale).points(), dtype=float)
    faces = ConvexHull(points).simplices
    return mg.TriangularMeshGeometry(points, faces), True


def _pose(rotation: Matrix, translation: Vector) -> Matrix:
    """Homogeneous transform (4, 4) of a rotation (3, 3) and a translation (3,) in [m]."""
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = translation
    return pose


def _rotation_z_to(axis: Vector) -> Matrix:
    """A rotation taking the z-axis onto the unit vector ``axis``."""
    return pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), axis).matrix()


def _rotation_y_to(axis: Vector) -> Matrix:
    """A rotation taking the y-axis (meshcat cylinders) onto the unit vector ``axis``."""
    return pin.Quaternion.FromTwoVectors(np.array([0.0, 1.0, 0.0]), axis).matrix()


def _up_rotation(gravity: Vector) -> Matrix:
    """Rotation taking the scene's up (-gravity; z without gravity) onto meshcat's z-axis."""
    norm = float(np.linalg.norm(gravity))
    if norm == 0.0:
        return np.eye(3)
    up = -gravity / norm
    return pin.Quaternion.FromTwoVectors(up, np.array([0.0, 0.0, 1.0])).matrix()


def _configurations(
    configurations: NDArray[np.float64] | None, q0: Vector, nq: int
) -> NDArray[np.float64]:
    if configurations is None:
        return q0.reshape(1, -1)
    array = np.asarray(configurations, dtype=float)
    if array.ndim != 2 or array.shape[1] != nq or array.shape[0] == 0:
        raise InvalidParameterError("configurations", array.shape, f"shape (K >= 1, {nq})")
    return array


def _bounds(points: Matrix, radii: Sequence[float]) -> tuple[Vector, float]:
    """Centre and radius in [m] of a sphere around ``points`` (N, 3) with a margin."""
    low, high = points.min(axis=0), points.max(axis=0)
    half_diagonal = 0.5 * float(np.linalg.norm(high - low))
    margin = max(0.1 * half_diagonal, max(radii, default=0.0), 0.05)  # bodies around frames
    return 0.5 * (low + high), half_diagonal + margin


def _force_scale(value: float | None, model: pin.Model, gravity: Vector, radius: float) -> float:
    if value is not None:
        if not np.isfinite(value) or value <= 0.0:
            raise InvalidParameterError("force_scale", value, "> 0 [m/N]")
        return float(value)
    mass = sum(inertia.mass for inertia in model.inertias)  # [kg]
    weight = mass * (float(np.linalg.norm(gravity)) or 9.81)  # [N]
    return WEIGHT_ARROW * radius / weight if weight > 0.0 else WEIGHT_ARROW * radius


def _view_direction(points_viewer: Matrix) -> Vector:
    """Unit vector from the centre of the view to the camera, in meshcat's world.

    A motion in a plane is seen from the normal of that plane (lifted a little); otherwise
    from the front right, above.
    """
    centred = points_viewer - points_viewer.mean(axis=0)
    _, spread, axes = np.linalg.svd(centred, full_matrices=False)
    spread = np.concatenate([spread, np.zeros(3 - spread.size)])
    preferred = np.array([0.5, -1.0, 0.0])
    if spread[0] > 0.0 and spread[2] < 0.15 * spread[0] <= spread[1] and axes.shape[0] == 3:
        normal = axes[2]
        if abs(normal[2]) > 0.9:  # a horizontal motion: from above
            direction = np.array([0.0, 0.0, 1.0]) + 0.5 * preferred
        else:
            direction = normal if normal @ preferred >= 0.0 else -normal
            direction = direction + np.array([0.0, 0.0, 0.3])
    else:
        direction = np.array([0.8, -1.2, 0.7])
    return direction / np.linalg.norm(direction)


def _set_camera(viewer: meshcat.Visualizer, position: Vector) -> None:
    """Put meshcat's default camera at ``position`` (meshcat world, [m]), looking at 0."""
    # The camera node is turned by +90 deg about x (three.js is y-up): local = (x, z, -y).
    viewer["/Cameras/default/rotated/<object>"].set_property(
        "position", [float(position[0]), float(position[2]), float(-position[1])]
    )


def _visual_geometry(scene: Scene, colour: tuple[float, ...]) -> pin.GeometryModel:
    """The URDF's visual geometry, completed with shapes for the bodies that have none.

    A joint whose body has no visual gets a sphere and a cylinder to each joint and frame it
    carries; a contact sphere (radius > 0) on such a body is drawn too.
    """
    robot = scene.robot
    model = robot.model
    if robot.urdf_path is None:
        geometry = pin.GeometryModel()
    else:
        package_dirs = [str(path) for path in robot.urdf_path.parents]  # package:// lookups
        geometry = pin.buildGeomFromUrdf(
            model, str(robot.urdf_path), pin.GeometryType.VISUAL, package_dirs=package_dirs
        )
    for obj in geometry.geometryObjects:
        if isinstance(obj.geometry, coal.ShapeBase) and np.allclose(
            obj.meshColor, _URDF_DEFAULT_COLOUR
        ):
            obj.meshColor = np.array(colour)
    drawn = {obj.parentJoint for obj in geometry.geometryObjects}
    size = 0.02 * max(_robot_length(model), 0.1)  # [m] radius of the skeleton
    for joint in range(1, model.njoints):
        if joint in drawn:
            continue
        _add_shape(geometry, f"skeleton_{joint}", joint, coal.Sphere(1.5 * size), np.eye(4), colour)
        ends = [model.jointPlacements[child].translation for child in model.children[joint]]
        ends += [
            frame.placement.translation
            for frame in model.frames
            if frame.parentJoint == joint and frame.type != pin.FrameType.JOINT
        ]
        distinct = {tuple(np.round(end, 9)) for end in ends if np.linalg.norm(end) > 1e-6}
        for k, end in enumerate(np.array(sorted(distinct)).reshape(-1, 3)):
            length = float(np.linalg.norm(end))  # [m]
            pose = _pose(_rotation_z_to(end / length), 0.5 * end)
            _add_shape(
                geometry, f"skeleton_{joint}_{k}", joint, coal.Cylinder(size, length), pose, colour
            )
    for i, contact in enumerate(scene.contacts):
        frame = model.frames[robot.frame_id(contact.frame)]
        if contact.radius > 0.0 and frame.parentJoint not in drawn:
            sphere = coal.Sphere(contact.radius)
            pose = frame.placement.homogeneous
            _add_shape(geometry, f"contact_{i}", frame.parentJoint, sphere, pose, colour)
    return geometry


def _add_shape(
    geometry: pin.GeometryModel,
    name: str,
    joint: int,
    shape: coal.ShapeBase,
    pose: Matrix,
    colour: tuple[float, ...],
) -> None:
    obj = pin.GeometryObject(name, joint, pin.SE3(pose), shape)
    obj.meshColor = np.array(colour)
    geometry.addGeometryObject(obj)


def _robot_length(model: pin.Model) -> float:
    """Sum of the distances between consecutive joints in [m], a size of the robot."""
    return float(sum(np.linalg.norm(p.translation) for p in model.jointPlacements[1:]))
