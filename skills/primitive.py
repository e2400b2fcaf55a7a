"""Movement primitives: a DMP with its parameters and what it is for, saved as JSON + NPZ.

A :class:`MovementPrimitive` is the unit that is learned, stored, optimised and executed: a joint-space
:class:`~besman.skills.dmp.DMP` (``space="joint"``, for a robot's joint group) or a
:class:`~besman.skills.cartesian_dmp.CartesianDMP` (``space="cartesian"``, for a frame such as a grasp
site), with a name and free-form provenance (where it came from, how it was learned).

On disk a primitive is two files: ``NAME.json`` (schema version, metadata, the DMP's configuration, and the
SHA-256 of the arrays) and ``NAME.npz`` (the arrays, loaded without pickle). Both are written atomically;
loading validates the schema, the checksum, every shape and every value, and names the file and field of
anything wrong.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from besman.core.errors import InputError
from besman.core.storage import (
    check_schema_version,
    npz_bytes,
    optional_field,
    read_json,
    read_npz,
    require_field,
    sha256,
    write_atomically,
)
from besman.core.validation import PATH, checked, instance, optional, text
from besman.skills.cartesian_dmp import CartesianDMP
from besman.skills.dmp import DMP
from besman.skills.dmp_core import DMPSettings, Primitive

SCHEMA_VERSION = 1
SPACES = ("joint", "cartesian")
_SCALARS = ("execution_time", "dt", "alpha_y", "beta_y", "final_phase", "overlap")
_POSITION_ARRAYS = (
    "scale",
    "start",
    "start_velocity",
    "start_acceleration",
    "goal",
    "goal_velocity",
    "weights",
)
_ROTATION_ARRAYS = (
    "rotation_scale",
    "start_orientation",
    "start_angular_velocity",
    "goal_orientation",
    "rotation_weights",
)


@checked(
    name=text("a primitive name"),
    robot=optional(text("a robot name")),
    group=optional(text("a joint group name")),
    frame=optional(text("a site or frame name")),
    provenance=instance(dict, "a dict"),
)
@dataclass
class MovementPrimitive:
    """A DMP together with its parameters and metadata.

    Attributes:
        dmp: the primitive: a joint-space :class:`DMP` or a :class:`CartesianDMP` (the kinds that are saved).
        name: a name people use for it ("reach", "throw").
        space: "joint" or "cartesian" (must match the DMP's kind).
        robot: the robot it is for (``besman.robots.available()``), if any.
        group: the joint group it drives (joint space), if any.
        frame: the site or frame it moves (Cartesian space), if any.
        provenance: JSON-compatible facts about its origin (demonstrations, learner, date, ...).
    """

    dmp: Primitive
    name: str
    space: str = "joint"
    robot: str | None = None
    group: str | None = None
    frame: str | None = None
    provenance: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.space not in SPACES:
            raise InputError(f"space must be one of {SPACES}, got {self.space!r}")
        expected = CartesianDMP if self.space == "cartesian" else DMP
        if not isinstance(self.dmp, expected):
            raise InputError(
                f"a {self.space}-space primitive needs a {expected.__name__}, got {type(self.dmp).__name__}"
            )
        try:
            json.dumps(self.provenance)
        except TypeError as error:
            raise InputError(f"provenance must be JSON-compatible: {error}") from None

    @property
    def theta(self) -> np.ndarray:
        """The DMP's parameter vector (``dmp.get_params()``)."""
        return self.dmp.get_params()

    @checked(path=PATH)
    def save(self, path: str | Path) -> Path:
        """Writes ``path`` (``.json``) and its arrays beside it (``.npz``); returns the JSON path."""
        json_path = _json_path(path)
        document, arrays = primitive_parts(self)
        data = npz_bytes(arrays)
        document = {
            "schema_version": SCHEMA_VERSION,
            "kind": "movement_primitive",
            **document,
            "arrays": {"file": json_path.with_suffix(".npz").name, "sha256": sha256(data)},
        }
        write_atomically(json_path.with_suffix(".npz"), data)
        write_atomically(json_path, (json.dumps(document, indent=2) + "\n").encode("utf-8"))
        return json_path

    @classmethod
    @checked(path=PATH)
    def load(cls, path: str | Path) -> MovementPrimitive:
        """Reads a primitive written by :meth:`save`; a ``ValueError`` names the file and the problem."""
        json_path = _json_path(path)
        document = read_json(json_path, what="primitive")
        where = str(json_path)
        check_schema_version(document, SCHEMA_VERSION, where)
        if document.get("kind") != "movement_primitive":
            raise InputError(f"{where}: kind must be 'movement_primitive', got {document.get('kind')!r}")
        reference = require_field(document, "arrays", dict, where)
        npz_name = require_field(reference, "file", str, f"{where}: arrays")
        if Path(npz_name).name != npz_name:
            raise InputError(f"{where}: arrays.file must be a file name beside the JSON, got {npz_name!r}")
        arrays = read_npz(
            json_path.parent / npz_name,
            require_field(reference, "sha256", str, f"{where}: arrays"),
            what="primitive's arrays",
        )
        return primitive_from_parts(document, arrays, where)


def primitive_parts(primitive: MovementPrimitive) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """A primitive as a JSON-compatible document (metadata and the DMP's configuration) and its arrays (what
    :meth:`MovementPrimitive.save` writes, and what files that embed a primitive store)."""
    config, arrays = _dmp_state(primitive.dmp)
    document = {
        "name": primitive.name,
        "space": primitive.space,
        "robot": primitive.robot,
        "group": primitive.group,
        "frame": primitive.frame,
        "provenance": primitive.provenance,
        "dmp": config,
    }
    return document, arrays


def primitive_from_parts(
    document: dict[str, Any], arrays: dict[str, np.ndarray], where: str
) -> MovementPrimitive:
    """The primitive of :func:`primitive_parts`; an :class:`InputError` starts with ``where``."""
    try:
        return MovementPrimitive(
            dmp=_restore_dmp(require_field(document, "dmp", dict, where), arrays),
            name=require_field(document, "name", str, where),
            space=require_field(document, "space", str, where),
            robot=optional_field(document, "robot", str, where),
            group=optional_field(document, "group", str, where),
            frame=optional_field(document, "frame", str, where),
            provenance=require_field(document, "provenance", dict, where),
        )
    except ValueError as error:
        message = str(error)
        raise InputError(message if message.startswith(where) else f"{where}: {message}") from None


def _json_path(path: str | Path) -> Path:
    path = Path(path)
    return path if path.suffix == ".json" else path.with_name(path.name + ".json")


def _dmp_state(dmp: DMP | CartesianDMP) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    position = dmp.position if isinstance(dmp, CartesianDMP) else dmp
    config = {
        "type": type(dmp).__name__,
        "n_dims": position.n_dims,
        "n_weights": position.n_weights,
        "execution_time": position.execution_time,
        "dt": position.dt,
        "alpha_y": position.settings.alpha_y,
        "beta_y": position.settings.beta_y,
        "final_phase": position.settings.final_phase,
        "overlap": position.settings.overlap,
    }
    arrays = {name: np.asarray(getattr(position, name), dtype=float) for name in _POSITION_ARRAYS}
    if isinstance(dmp, CartesianDMP):
        arrays |= {name: np.asarray(getattr(dmp, name), dtype=float) for name in _ROTATION_ARRAYS}
    return config, arrays


def _restore_dmp(config: dict[str, Any], arrays: dict[str, np.ndarray]) -> DMP | CartesianDMP:
    kind = config.get("type")
    if kind not in ("DMP", "CartesianDMP"):
        raise InputError(f"dmp.type must be 'DMP' or 'CartesianDMP', got {kind!r}")
    # NaN and infinities (which Python's JSON reads) are refused by the DMP and its settings, with the name.
    scalars = {name: float(require_field(config, name, (int, float), "dmp")) for name in _SCALARS}
    n_weights = require_field(config, "n_weights", int, "dmp")
    names = _POSITION_ARRAYS + (_ROTATION_ARRAYS if kind == "CartesianDMP" else ())
    missing = [name for name in names if name not in arrays]
    if missing:
        raise InputError(f"the arrays lack {', '.join(missing)}")
    vectors = {name: arrays[name] for name in names if "weights" not in name}
    settings = DMPSettings(
        n_weights, *(scalars.pop(name) for name in ("alpha_y", "beta_y", "final_phase", "overlap"))
    )
    if kind == "DMP":
        n_dims = require_field(config, "n_dims", int, "dmp")
        dmp = DMP(n_dims, settings=settings, **scalars, **vectors)
        dmp.weights = _weights("weights", arrays["weights"], (n_dims, n_weights))
        return dmp
    cartesian = CartesianDMP(
        settings=settings,
        **scalars,
        scale=vectors["scale"],
        start_position=vectors["start"],
        start_velocity=vectors["start_velocity"],
        goal_position=vectors["goal"],
        goal_velocity=vectors["goal_velocity"],
        rotation_scale=vectors["rotation_scale"],
        start_orientation=vectors["start_orientation"],
        start_angular_velocity=vectors["start_angular_velocity"],
        goal_orientation=vectors["goal_orientation"],
    )
    cartesian.position.start_acceleration = _weights(
        "start_acceleration", vectors["start_acceleration"], (3,)
    )
    cartesian.position.weights = _weights("weights", arrays["weights"], (3, n_weights))
    cartesian.rotation_weights = _weights("rotation_weights", arrays["rotation_weights"], (3, n_weights))
    return cartesian


def _weights(name: str, value: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    if value.shape != shape:
        raise InputError(f"array {name!r} must have shape {shape}, got {value.shape}")
    if not np.issubdtype(value.dtype, np.floating) or not np.all(np.isfinite(value)):
        raise InputError(f"array {name!r} must hold finite floats")
    return value.astype(float)
