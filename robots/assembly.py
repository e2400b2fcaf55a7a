"""Assembling a robot's model from its description: the model file, attached parts, mount, stage and tool
frames, as one ``mujoco.MjSpec`` that worlds add furniture to before compiling.

The steps, in order (each from a field of ``description.json``, see :mod:`besman.robots.description`):

1. the model: a file beside the description, a Menagerie file (:mod:`besman.robots.menagerie`), or a file
   an installed package ships (:mod:`besman.robots.packages`);
2. ``options``: simulation options set on the whole, before parts are attached: at attach the parent's
   options win over a part's own (e.g. the Robotiq 2F-85's ``impratio=10`` and elliptic cones, which the
   description therefore sets);
3. ``attach``: each part's spec attached at a site of the model, or a body's origin (``MjSpec.attach``), its
   names prefixed;
   MuJoCo extends the keyframes with the part's joints and actuators (at their defaults); ``servos``: a
   position actuator on each joint named, in place of what drove it, the keyframes' controls following;
4. ``gravity_compensation``: every body of the robot (parts included) weightless to its actuators;
5. ``mount``: the root bodies moved (turned by yaw about z, then shifted), so the robot stands where its
   tabletop layout expects it;
6. ``floor``: besman's stage (the floor, lights and sky of the shipped robots' ``scene.xml``) for a model
   that has none, with a pedestal under a robot mounted above the floor;
7. the arms' tool-centre points given as an offset on a body become sites, and ``exclude`` pairs become
   contact exclusions;
8. ``home``: the keyframe for a model that has none, at the model's reference configuration except the
   joints it names; every actuator that drives one joint is commanded to that joint's position there.
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.core.validation import checked, instance
from besman.robots import menagerie, packages
from besman.robots.description import DescriptionError, ModelSource, RobotDescription
from besman.robots.fields import finite_number
from besman.robots.model_files import check_assets_found, check_model_files

JOINT = mujoco.mjtTrn.mjTRN_JOINT
NOT_LIMITED = mujoco.mjtLimited.mjLIMITED_FALSE
# Options that name a choice, spelt as MJCF spells them.
CHOICES = {
    "cone": {"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL, "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC},
    "integrator": {
        "Euler": mujoco.mjtIntegrator.mjINT_EULER,
        "RK4": mujoco.mjtIntegrator.mjINT_RK4,
        "implicit": mujoco.mjtIntegrator.mjINT_IMPLICIT,
        "implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
    },
}
# Options counted in whole numbers (solver iterations: noslip_iterations > 0 turns on the no-slip solver),
# and the most of each that is not a slip of the keyboard (every step runs them).
WHOLE_OPTIONS = {"noslip_iterations": 1000}


def model_path(source: ModelSource, folder: Path, where: str) -> Path:
    """The file of a model source: beside the description (``folder``), in Menagerie, or in a package."""
    if source.menagerie:
        return menagerie.find(source.file, where)
    if source.package is not None:
        return packages.find(source.package, source.file, where)
    return _inside(folder, source.file, where)


def _inside(folder: Path, file: str, where: str) -> Path:
    """``folder / file``, refused if it resolves (symbolic links followed) outside ``folder``: a description
    names its own model, not any file of the machine."""
    path = folder / file
    if not path.resolve().is_relative_to(folder.resolve()):
        raise DescriptionError(
            f"{where}: {file!r} lies outside the robot's folder {folder} (it resolves to {path.resolve()}); "
            "name a file inside it, or a Menagerie or package model"
        )
    return path


def _spec(path: Path, where: str) -> mujoco.MjSpec:
    """The model file ``path`` parsed, its asset files found (``where``: the field that names it)."""
    check_model_files(path)  # MuJoCo opens them by path, with no check of its own
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except ValueError as error:
        hint = ""
        if "mujocoinclude" in str(error):  # packages often ship fragments, not models
            hint = (
                ": it is a fragment for other models to include; give as the model a file of your own beside "
                "the description that includes it where it belongs (<mujoco><worldbody><include "
                f'file="{path}"/></worldbody></mujoco> for bodies, inside <asset> for assets), with '
                '<compiler meshdir="..."/> the absolute folder of its meshes if they are not beside it'
            )
        raise InputError(f"{path}: the model does not load: {error}{hint}") from None
    check_assets_found(spec, where)
    return spec


def _turn(yaw: float) -> np.ndarray:
    return np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])


def _mount(spec: mujoco.MjSpec, position, yaw: float) -> None:
    """Moves every root body (a child of the world body): turned by ``yaw`` about z, then shifted."""
    turn = _turn(yaw)
    rotation = np.empty(9)
    mujoco.mju_quat2Mat(rotation, turn)
    for body in spec.worldbody.bodies:
        body.pos = rotation.reshape(3, 3) @ np.asarray(body.pos) + np.asarray(position)
        # The body's orientation as the model wrote it (euler, axisangle, ... take precedence over quat).
        own = body.quat
        if body.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
            own = spec.resolve_orientation(spec.compiler.degree, spec.compiler.eulerseq, body.alt)
        turned = np.empty(4)
        mujoco.mju_mulQuat(turned, turn, np.asarray(own) / np.linalg.norm(own))
        body.quat, body.alt.type = turned, mujoco.mjtOrientation.mjORIENTATION_QUAT


def add_stage(spec: mujoco.MjSpec) -> None:
    """The floor, lights and sky of the shipped robots' ``scene.xml`` (MuJoCo Menagerie's stage)."""
    spec.visual.headlight.diffuse = [0.6, 0.6, 0.6]
    spec.visual.headlight.ambient = [0.3, 0.3, 0.3]
    spec.visual.headlight.specular = [0.0, 0.0, 0.0]
    spec.visual.rgba.haze = [0.15, 0.25, 0.35, 1.0]
    spec.visual.global_.azimuth, spec.visual.global_.elevation = 150, -20
    spec.visual.global_.offwidth, spec.visual.global_.offheight = 1280, 960
    spec.add_texture(
        type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT,
        rgb1=[0.3, 0.5, 0.7],
        rgb2=[0, 0, 0],
        width=512,
        height=3072,
    )
    spec.add_texture(
        name="besman_groundplane",
        type=mujoco.mjtTexture.mjTEXTURE_2D,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        mark=mujoco.mjtMark.mjMARK_EDGE,
        rgb1=[0.2, 0.3, 0.4],
        rgb2=[0.1, 0.2, 0.3],
        markrgb=[0.8, 0.8, 0.8],
        width=300,
        height=300,
    )
    material = spec.add_material(
        name="besman_groundplane", texuniform=True, texrepeat=[5, 5], reflectance=0.2
    )
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "besman_groundplane"
    spec.worldbody.add_light(pos=[0, 0, 3.5], dir=[0, 0, -1], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL)
    spec.worldbody.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0, 0, 0.05], material="besman_groundplane"
    )


@checked(
    description=instance(RobotDescription, "a RobotDescription (robots.describe)"),
    meshes=instance(bool, "True or False"),
)
def build_spec(description: RobotDescription, *, meshes: bool = True) -> mujoco.MjSpec:
    """The robot's assembled, uncompiled model (see the module documentation); with ``meshes=False``
    :func:`without_meshes`."""
    where = str(description.file)
    spec = _spec(model_path(description.model, description.folder, f"{where}.model"), f"{where}.model")
    for name, value in description.options.items():
        field = f"{where}.options.{name}"
        if name in CHOICES:
            if not isinstance(value, str) or value not in CHOICES[name]:
                raise DescriptionError(f"{field}: one of {', '.join(CHOICES[name])}, got {value!r}")
            setattr(spec.option, name, CHOICES[name][value])
        elif name in WHOLE_OPTIONS:
            most = WHOLE_OPTIONS[name]
            if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= most:
                raise DescriptionError(f"{field}: expected a whole number from 0 to {most}, got {value!r}")
            setattr(spec.option, name, value)
        elif not finite_number(value, field) > 0:
            raise DescriptionError(f"{field}: expected a positive number, got {value!r}")
        else:
            setattr(spec.option, name, float(value))
    for index, part in enumerate(description.attach):
        part_where = f"{where}.attach[{index}]"
        child = _spec(
            model_path(part.model, description.folder, f"{part_where}.model"), f"{part_where}.model"
        )
        if part.body is not None:
            body = spec.body(part.body)
            if body is None:
                raise DescriptionError(f"{part_where}.body: the model has no body {part.body!r}")
            spec.attach(child, frame=body.add_frame(), prefix=part.prefix)
            continue
        site = spec.site(part.site)
        if site is None:
            raise DescriptionError(f"{part_where}.site: the model has no site {part.site!r}")
        spec.attach(child, site=site, prefix=part.prefix)
    if description.servos:
        _add_servos(spec, description)
    if description.gravity_compensation:
        for body in spec.worldbody.find_all(mujoco.mjtObj.mjOBJ_BODY):
            body.gravcomp = 1.0
    if description.mount is not None:
        _mount(spec, description.mount.position, description.mount.yaw)
    if description.floor:
        add_stage(spec)
        if description.mount is not None and description.mount.position[2] > 0:
            # A raised robot stands on a pedestal (drawn only: nothing the robot does reaches below its base);
            # cameras look at its arm, not at the pedestal.
            x, y, z = description.mount.position
            spec.stat.center = [x + 0.2, y, z + 0.2]
            spec.stat.extent = 1.2
            spec.worldbody.add_geom(
                name="pedestal",
                type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                pos=[x, y, z / 2],
                size=[0.09, z / 2, 0],
                rgba=[0.3, 0.3, 0.32, 1],
                contype=0,
                conaffinity=0,
            )
    for arm in description.arms.values():
        tcp = arm.tcp
        if tcp.body is None:
            continue
        body = spec.body(tcp.body)
        if body is None:
            raise DescriptionError(f"{where}.arms.{arm.name}.tcp.body: the model has no body {tcp.body!r}")
        body.add_site(name=tcp.site, pos=list(tcp.position), quat=list(tcp.quaternion))
    for first, second in description.exclude:
        spec.add_exclude(bodyname1=first, bodyname2=second)
    if not meshes:
        without_meshes(spec)
    if description.home:
        _add_home(spec, description)
    return spec


def _add_servos(spec: mujoco.MjSpec, description: RobotDescription) -> None:
    """A position actuator ``<joint>_servo`` on each joint of ``description.servos``, in place of the
    actuators that drove it (appended, in the description's order); the keyframes' controls follow (a
    servo's: its joint's position in the keyframe)."""
    servos = description.servos
    joints = {joint: spec.joint(joint) for joint in servos}
    for joint, found in joints.items():
        if found is None:
            raise DescriptionError(f"{description.file}.servos.{joint}: the model has no joint {joint!r}")
    actuators = list(spec.actuators)
    replaced = [a.trntype == JOINT and a.target in servos for a in actuators]
    controls = [
        [value for value, gone in zip(key.ctrl, replaced, strict=False) if not gone] for key in spec.keys
    ]
    for joint, servo in servos.items():
        force = servo.force
        for actuator, gone in zip(actuators, replaced, strict=True):
            if gone and actuator.target == joint and force is None and actuator.ctrllimited != NOT_LIMITED:
                force = float(abs(actuator.gear[0]) * np.abs(actuator.ctrlrange).max()) or None
        found = joints[joint]
        added = spec.add_actuator(name=f"{joint}_servo", target=joint, trntype=JOINT)
        added.set_to_position(kp=servo.kp, kv=servo.kv)
        if found.range[0] < found.range[1]:  # a joint without a range is refused with its group
            added.ctrlrange, added.ctrllimited = found.range, mujoco.mjtLimited.mjLIMITED_TRUE
        if force is not None:
            added.forcerange, added.forcelimited = [-force, force], mujoco.mjtLimited.mjLIMITED_TRUE
    for actuator, gone in zip(actuators, replaced, strict=True):
        if gone:
            spec.delete(actuator)
    for key in spec.keys:
        key.ctrl = []
    model = without_meshes(spec.copy()).compile()
    for index, key in enumerate(spec.keys):
        kept = controls[index] + [0.0] * (model.nu - len(servos) - len(controls[index]))
        at = model.key_qpos[index]
        key.ctrl = kept + [float(at[model.jnt_qposadr[model.joint(joint).id]]) for joint in servos]


def without_meshes(spec: mujoco.MjSpec) -> mujoco.MjSpec:
    """``spec`` with every mesh geom a 1 cm sphere and no mesh (no mesh file read), for what needs only the
    joints, actuators and keyframes: reading and processing meshes is most of a compile (the OpenArm's 94:
    1.0 of 1.05 s). Before compiling: deleting a compiled mesh costs as much again."""
    for geom in spec.geoms:
        if geom.type == mujoco.mjtGeom.mjGEOM_MESH:
            geom.type, geom.size, geom.meshname = mujoco.mjtGeom.mjGEOM_SPHERE, [0.01, 0.0, 0.0], ""
    for mesh in list(spec.meshes):
        spec.delete(mesh)
    return spec


def _add_home(spec: mujoco.MjSpec, description: RobotDescription) -> None:
    """The keyframe ``description.keyframe`` from ``description.home`` (see the module documentation)."""
    where = f"{description.file}.home"
    if spec.key(description.keyframe) is not None:
        raise DescriptionError(f"{where}: the model has its own keyframe {description.keyframe!r}; drop home")
    try:  # joints, actuators and their ranges: the meshes are not needed
        model = without_meshes(spec.copy()).compile()
    except ValueError as error:
        raise InputError(f"{description.file}: the robot's model does not compile: {error}") from None
    qpos = model.qpos0.copy()
    for joint, position in description.home.items():
        index = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, joint)
        if index < 0:
            raise DescriptionError(f"{where}.{joint}: the model has no joint {joint!r}")
        low, high = model.jnt_range[index]
        if model.jnt_limited[index] and not low <= position <= high:
            raise DescriptionError(f"{where}.{joint}: {position} outside the joint's range [{low}, {high}]")
        qpos[model.jnt_qposadr[index]] = position
    ctrl = np.zeros(model.nu)
    for actuator in range(model.nu):
        if model.actuator_trntype[actuator] == mujoco.mjtTrn.mjTRN_JOINT:
            ctrl[actuator] = qpos[model.jnt_qposadr[model.actuator_trnid[actuator, 0]]]
        if model.actuator_ctrllimited[actuator]:
            ctrl[actuator] = np.clip(ctrl[actuator], *model.actuator_ctrlrange[actuator])
    spec.add_key(name=description.keyframe, qpos=qpos.tolist(), ctrl=ctrl.tolist())
