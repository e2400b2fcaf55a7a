"""The skill template pool: templates persisted in a directory, read as a mapping of names to templates.

A :class:`SkillTemplatePool` is a directory (the embedded default of a pool: nothing to install or run) with
two files per template:

- ``NAME.json`` - the manifest: schema version, kind, name, task, the task parameters' names and box, the
  theta layout (the prototype primitive's document: DMP configuration and metadata), the model of Theta
  and its kernel (the shared model's hyperparameters, or the names of the per-dimension GPs'), the Omega
  kind, the training set's size, provenance, and the SHA-256 of
- ``NAME.npz`` - the arrays: training taus and thetas, the prototype's arrays, and the shared model's prior
  spread or the per-dimension GPs' fitted hyperparameters.

Nothing is pickled: a template is rebuilt from its training data and stored hyperparameters (the models
are refitted with their hyperparameters given, which reproduces their predictions exactly). Schema
version 2 added the model, version 3 the shared model's drift (constant or affine); entries of versions 1
(all per-dimension) and 2 (a constant drift) are still read. Writes go through temporary
files and renames (arrays first, manifest last) under an exclusive ``flock`` on the directory; reads hold
a shared one (and write nothing into it), so two writers, or a writer and a reader, never see half an
entry. An entry that is truncated, tampered with (its arrays no longer match the manifest's checksum), of
another schema version or not a template at all is refused with a :class:`PoolError` that names its file;
the other entries stay readable.

The pool is a ``Mapping[str, SkillTemplate]``, so the behaviour-tree leaf ``InstantiateSkillTemplate``
takes it as ``pool=`` and tree files name it by its directory.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import asdict
from pathlib import Path

import numpy as np

from besman.core.errors import BesmanError, UnknownNameError
from besman.core.reading import read_bytes
from besman.core.storage import (
    JSON_BYTES,
    check_schema_version,
    npz_bytes,
    read_json,
    read_npz,
    require_field,
    sha256,
    write_atomically,
)
from besman.core.validation import PATH, checked, instance
from besman.skills.primitive import primitive_from_parts, primitive_parts
from besman.skills.shared_kernel import SharedKernel
from besman.skills.task_bounds import TaskBounds
from besman.skills.template import EXPLORATIONS, SkillTemplate

SCHEMA_VERSION = 3
READABLE_VERSIONS = (1, 2, 3)  # 1: per-dimension templates, before the model was stored; 2: no drift
KIND = "besman-skill-template"
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,99}")
PROTOTYPE = "prototype."  # prefix of the prototype's arrays in the NPZ


class PoolError(BesmanError):
    """A pool or one of its entries cannot be used; the message names the directory or file."""


class SkillTemplatePool(Mapping[str, SkillTemplate]):
    """The templates in ``directory`` (created on the first :meth:`add`)."""

    @checked(directory=PATH)
    def __init__(self, directory: str | Path) -> None:
        self.directory = Path(directory)
        if self.directory.exists() and not self.directory.is_dir():
            raise PoolError(f"{self.directory}: a pool is a directory, this is a file")
        self._cache: dict[str, tuple[str, SkillTemplate]] = {}  # name -> (manifest checksum, template)

    # -- the mapping ---------------------------------------------------------------------------------------

    def __iter__(self) -> Iterator[str]:
        if not self.directory.is_dir():
            return iter(())
        return iter(sorted(path.stem for path in self.directory.glob("*.json") if NAME.fullmatch(path.stem)))

    def __len__(self) -> int:
        return sum(1 for _ in self)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and NAME.fullmatch(name) is not None and self._manifest(name).exists()

    def __getitem__(self, name: str) -> SkillTemplate:
        if name not in self:
            raise self._unknown(name)
        with self._lock(shared=True):
            manifest = self._manifest(name)
            text = read_bytes(manifest, JSON_BYTES, what="pool manifest", error=PoolError)
            checksum = sha256(text)
            cached = self._cache.get(name)
            if cached is not None and cached[0] == checksum:
                return cached[1]
            template = self._read(name, manifest)
        self._cache[name] = (checksum, template)
        return template

    def problems(self) -> dict[str, str]:
        """Each entry that cannot be read, with the reason (the others are fine)."""
        found = {}
        for name in self:
            try:
                self[name]
            except PoolError as error:
                found[name] = str(error)
        return found

    # -- writing -------------------------------------------------------------------------------------------

    @checked(template=instance(SkillTemplate, "a SkillTemplate"), overwrite=instance(bool, "True or False"))
    def add(self, template: SkillTemplate, *, overwrite: bool = False) -> Path:
        """Stores ``template`` under its name; an existing entry is replaced only with ``overwrite``."""
        if NAME.fullmatch(template.name) is None:
            raise PoolError(
                f"{template.name!r} is not a pool entry name (letters, digits, '_', '.', '-'; up to 100)"
            )
        prototype, prototype_arrays = primitive_parts(template.prototype)
        arrays = {
            "taus": template.taus,
            "thetas": template.thetas,
            **{PROTOTYPE + key: value for key, value in prototype_arrays.items()},
        }
        if template.kernel is None:
            from besman.skills.template_models import per_dimension_kernel  # scikit-learn: only needed here

            arrays["hyperparameters"] = template.hyperparameters
            kernel = {
                "model": "per_dimension",
                "form": "C * RBF(anisotropic) + White, per theta dimension",
                "hyperparameters": [
                    param.name for param in per_dimension_kernel(len(template.box.names)).hyperparameters
                ],
            }
        else:
            arrays["prior_spread"] = template.prior_spread
            kernel = {"model": "shared", **asdict(template.kernel)}
        data = npz_bytes(arrays)
        manifest = self._manifest(template.name)
        document = {
            "schema_version": SCHEMA_VERSION,
            "kind": KIND,
            "name": template.name,
            "task": template.task,
            "tau": template.box.as_dict(),
            "theta": {"size": int(template.thetas.shape[1]), "prototype": prototype},
            "exploration": template.exploration,
            "kernel": kernel,
            "training": {"tasks": len(template.taus), "seed": template.seed},
            "provenance": template.provenance,
            "arrays": {"file": manifest.with_suffix(".npz").name, "sha256": sha256(data)},
        }
        self.directory.mkdir(parents=True, exist_ok=True)
        with self._lock(shared=False):
            if manifest.exists() and not overwrite:
                raise PoolError(
                    f"{manifest}: the pool already has {template.name!r} (overwrite=True replaces it)"
                )
            write_atomically(manifest.with_suffix(".npz"), data)
            write_atomically(manifest, (json.dumps(document, indent=2) + "\n").encode("utf-8"))
        return manifest

    def remove(self, name: str) -> None:
        if name not in self:
            raise self._unknown(name)
        with self._lock(shared=False):
            manifest = self._manifest(name)
            manifest.unlink()  # manifest first: a half-removed entry is simply absent
            manifest.with_suffix(".npz").unlink(missing_ok=True)
        self._cache.pop(name, None)

    # -- internals -----------------------------------------------------------------------------------------

    def _unknown(self, name: str) -> UnknownNameError:
        templates = ", ".join(self) or "none"
        return UnknownNameError(f"pool {self.directory}: no template {name!r}; templates: {templates}")

    def _manifest(self, name: str) -> Path:
        return self.directory / f"{name}.json"

    @contextmanager
    def _lock(self, *, shared: bool):
        """A shared (reads) or exclusive (writes) ``flock`` on the directory itself: a read writes nothing
        into the user's folder and works on a pool nobody here may write (e.g. installed with the package)."""
        try:
            descriptor = os.open(self.directory, os.O_RDONLY | os.O_DIRECTORY)
        except (FileNotFoundError, NotADirectoryError):
            raise PoolError(f"{self.directory}: no such pool directory") from None
        except PermissionError:
            raise PoolError(f"{self.directory}: the pool's directory may not be read here") from None
        try:
            if not shared and not os.access(self.directory, os.W_OK):
                raise PoolError(f"{self.directory}: the pool is read-only here")
            fcntl.flock(descriptor, fcntl.LOCK_SH if shared else fcntl.LOCK_EX)
            yield
        finally:
            os.close(descriptor)  # which releases the lock

    def _read(self, name: str, manifest: Path) -> SkillTemplate:
        where = str(manifest)
        try:
            document = read_json(manifest, PoolError, what="pool manifest")
            if document is None or document.get("kind") != KIND:
                found = None if document is None else document.get("kind")
                raise PoolError(f"{where}: not a skill template (kind {found!r}, expected {KIND!r})")
            check_schema_version(document, READABLE_VERSIONS, where, PoolError)
            if require_field(document, "name", str, where) != name:
                raise PoolError(f"{where}: the manifest names {document['name']!r}, its file {name!r}")
            reference = require_field(document, "arrays", dict, where)
            npz_name = require_field(reference, "file", str, f"{where}: arrays")
            if npz_name != manifest.with_suffix(".npz").name:
                raise PoolError(f"{where}: arrays.file must be {manifest.with_suffix('.npz').name!r}")
            arrays = read_npz(
                manifest.with_suffix(".npz"),
                require_field(reference, "sha256", str, f"{where}: arrays"),
                what="pool entry's arrays",
            )
            tau = require_field(document, "tau", dict, where)
            ranges = [require_field(tau, name, list, f"{where}: tau") for name in tau]
            if not tau or any(len(pair) != 2 for pair in ranges):
                raise PoolError(f"{where}: tau must map each task parameter to [low, high]")
            box = TaskBounds(tuple(tau), *(tuple(float(pair[i]) for pair in ranges) for i in (0, 1)))
            theta = require_field(document, "theta", dict, where)
            prototype = primitive_from_parts(
                require_field(theta, "prototype", dict, f"{where}: theta"),
                {key[len(PROTOTYPE) :]: value for key, value in arrays.items() if key.startswith(PROTOTYPE)},
                f"{where}: theta.prototype",
            )
            exploration = require_field(document, "exploration", str, where)
            if exploration not in EXPLORATIONS:
                raise PoolError(f"{where}: exploration must be one of {EXPLORATIONS}, got {exploration!r}")
            for key in ("taus", "thetas"):
                if key not in arrays:
                    raise PoolError(f"{where}: the arrays lack {key!r}")
            training = require_field(document, "training", dict, where)
            return SkillTemplate(
                name,
                prototype,
                arrays["taus"],
                arrays["thetas"],
                box,
                exploration=exploration,
                **_model(document, arrays, where),
                seed=require_field(training, "seed", int, f"{where}: training"),
                task=require_field(document, "task", str, where),
                provenance=require_field(document, "provenance", dict, where),
            )
        except PoolError:
            raise
        except ValueError as error:  # the project's InputError and numpy's own, from any field or array
            message = str(error)
            raise PoolError(message if message.startswith(where) else f"{where}: {message}") from None


def _model(document: dict, arrays: dict[str, np.ndarray], where: str) -> dict:
    """The template's model arguments from a manifest's kernel (version 1: always per-dimension)."""
    kernel = require_field(document, "kernel", dict, where)
    model = "per_dimension" if document["schema_version"] == 1 else require_field(kernel, "model", str, where)
    needs = {"per_dimension": "hyperparameters", "shared": "prior_spread"}
    if model not in needs:
        raise PoolError(f"{where}: kernel.model must be one of {sorted(needs)}, got {model!r}")
    if needs[model] not in arrays:
        raise PoolError(f"{where}: the arrays lack {needs[model]!r}")
    if model == "per_dimension":
        return {"model": model, "hyperparameters": arrays["hyperparameters"]}
    fields = {
        field: require_field(kernel, field, (int, float), f"{where}: kernel")
        for field in ("length_scale", "noise", "prior_weight")
    }
    fields["weights"] = require_field(kernel, "weights", str, f"{where}: kernel")
    if document["schema_version"] >= 3:  # version 2: before the drift was a choice, always constant
        fields["drift"] = require_field(kernel, "drift", str, f"{where}: kernel")
    return {"model": model, "kernel": SharedKernel(**fields), "prior_spread": arrays["prior_spread"]}


def summary(template: SkillTemplate) -> dict:
    """What ``besman pool show`` prints: the template's facts as plain data."""
    return {
        "name": template.name,
        "task": template.task,
        "tau": template.box.as_dict(),
        "theta_size": int(template.thetas.shape[1]),
        "prototype": template.prototype.name,
        "exploration": template.exploration,
        "training_tasks": len(template.taus),
        "model": template.model_name,
        **(
            {"hyperparameters": np.round(template.hyperparameters, 4).tolist()}
            if template.kernel is None
            else {"kernel": asdict(template.kernel)}
        ),
        "provenance": template.provenance,
    }
