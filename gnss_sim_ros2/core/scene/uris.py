"""Resource URIs resolved as Gazebo resolves them, from local files only (never the network).

* ``model://NAME[/path]``: the folders of ``GZ_SIM_RESOURCE_PATH``, ``IGN_GAZEBO_RESOURCE_PATH``,
  ``GAZEBO_MODEL_PATH`` and ``SDF_PATH`` (colon separated, in that order: gz-sim's
  ``resourcePaths()``, Gazebo Classic and sdformat's ``findFile``), then the folder of the including
  file and of the world file.
* Fuel, ``http(s)://SERVER[/1.0]/OWNER/models/NAME[/VERSION|tip][/files/PATH]`` (gz-fuel-tools'
  URL patterns): the local Fuel cache, ``GZ_FUEL_CACHE_PATH`` when set, else ``~/.gz/fuel`` (then the
  older ``~/.ignition/fuel``), laid out ``CACHE/SERVER/OWNER/models/NAME/VERSION/``.  Fuel stores
  owner and name in lower case; they are matched case-insensitively, ``%20`` is a space; without a
  version (or ``tip``) the highest numbered version folder is taken.  Other http(s) URIs are an error.
  Inside a cached Fuel model, ``model://ANY/path`` not found on the resource paths is the model's own
  ``path`` (gz-fuel-tools rewrites such URIs to the model itself on download, since Dome).
* ``file://PATH`` or a bare path: absolute as is; relative first to the including file's folder
  (gz-sim ``asFullPath``), then to the world's folder, then to each resource folder (gz-sim's
  resource lookup strips ``file://`` and searches the resource paths).
* ``package://PKG/path`` (ROS): ``PREFIX/share/PKG`` for each ``AMENT_PREFIX_PATH`` prefix, ``DIR/PKG``
  (or ``DIR`` itself when named PKG) for each ``ROS_PACKAGE_PATH`` folder, then as ``model://``
  (gz-sim treats ``package://`` like ``model://``).

A model folder's SDF is named by ``model.config`` (the ``<sdf>`` of highest version, as
gz-fuel-tools picks it), else ``model.sdf``.
"""
from __future__ import annotations

import os
import re
from pathlib import Path
from urllib.parse import unquote

from .sdf_xml import SdfError, parse_xml, where

#: environment variables searched for ``model://`` URIs, in this order
RESOURCE_PATH_VARS = ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "GAZEBO_MODEL_PATH", "SDF_PATH")
#: Gazebo Classic's own model folder, always searched (its SystemPaths default), last
CLASSIC_MODEL_DIR = Path.home() / ".gazebo" / "models"

# gz-fuel-tools FuelClient kModelUrlRegexStr / kModelFileUrlRegexStr, one pattern
_FUEL_URL = re.compile(r"^https?://(?P<server>[^/\s]+)/+(?:[0-9]+\.[0-9]+/+)?(?P<owner>[^/\s]+)/+models/+"
                       r"(?P<name>[^/]+?)(?:/+(?P<version>[0-9]+|tip))?(?:/+files/+(?P<path>.*?))?/*$")


def env_dirs(var: str) -> list[Path]:
    return [Path(p.strip()) for p in os.environ.get(var, "").split(os.pathsep) if p.strip()]


def resource_dirs(extra: list[Path] | None = None) -> list[Path]:
    """Folders searched for ``model://`` URIs (environment variables, then ``extra``)."""
    out = []
    for var in RESOURCE_PATH_VARS:
        out.extend(env_dirs(var))
    out.extend(extra or [])
    return out


def fuel_cache_roots() -> list[Path]:
    """Local Fuel caches: ``GZ_FUEL_CACHE_PATH`` if set (as gz-fuel-tools ClientConfig), else the defaults."""
    env = os.environ.get("GZ_FUEL_CACHE_PATH", "").strip()
    if env:
        return [Path(env)]
    home = Path.home()
    return [home / ".gz" / "fuel", home / ".ignition" / "fuel"]


def _children_ci(folder: Path, name: str) -> list[Path]:
    """Entries of ``folder`` named ``name`` case-insensitively (the exact spelling first)."""
    if not folder.is_dir():
        return []
    low = name.lower()
    hits = [c for c in folder.iterdir() if c.name.lower() == low]
    return sorted(hits, key=lambda c: (c.name != name, c.name))


def fuel_model_dir(uri: str) -> tuple[Path | None, str, list[Path]]:
    """(model version folder or None, file path inside it, folders looked at) for a Fuel model URL."""
    m = _FUEL_URL.match(uri.strip())
    if m is None:
        return None, "", []
    server, owner, name = (unquote(m.group(k)) for k in ("server", "owner", "name"))
    version, sub = m.group("version"), unquote(m.group("path") or "")
    looked = []
    for root in fuel_cache_roots():
        looked.append(root / server / owner.lower() / "models" / name.lower())
        folders = [root / server]
        for part in (owner, "models", name):
            folders = [c for d in folders for c in _children_ci(d, part)]
        for folder in folders:
            versions = [d for d in folder.iterdir() if d.is_dir() and d.name.isdigit()]
            if version and version != "tip":
                chosen = [d for d in versions if int(d.name) == int(version)]
            else:
                chosen = sorted(versions, key=lambda d: int(d.name))[-1:]
            if chosen:
                return chosen[0], sub, looked
    return None, sub, looked


def _fuel_version_dir(folder: Path) -> Path | None:
    """The Fuel model version folder (``.../OWNER/models/NAME/VERSION``) that holds ``folder``, if any."""
    for p in [folder, *folder.parents]:
        if p.name.isdigit() and p.parent.parent.name.lower() == "models" and (p / "model.config").is_file():
            return p
    return None


def _package_dirs(pkg: str) -> list[Path]:
    out = [p / "share" / pkg for p in env_dirs("AMENT_PREFIX_PATH")]
    for d in env_dirs("ROS_PACKAGE_PATH"):
        out.append(d if d.name == pkg else d / pkg)
    return out


class UriResolver:
    """Resolve URIs of one world (its folder is a search folder); messages name the element."""

    def __init__(self, world_dir: Path):
        self.world_dir = Path(world_dir)

    def resolve(self, uri: str, base_dir: Path, el=None, file="<sdf>") -> Path:
        """An existing path for ``uri`` seen from a file in ``base_dir``; SdfError naming what was searched."""
        uri = (uri or "").strip()
        at = where(el, file) if el is not None else str(file)
        if not uri:
            raise SdfError(f"{at}: empty <uri>")
        low = uri.lower()
        if low.startswith(("http://", "https://")):
            return self._fuel(uri, at)
        if low.startswith("model://"):
            rest = uri[len("model://"):]
            try:
                return self._search(rest, self._model_dirs(base_dir), uri, at, "set GZ_SIM_RESOURCE_PATH (or "
                                    "GAZEBO_MODEL_PATH) to the folder that holds the model")
            except SdfError:
                own, inner = _fuel_version_dir(Path(base_dir)), rest.partition("/")[2]
                if own is not None and inner and (own / inner).exists():
                    return own / inner
                raise
        if low.startswith("package://"):
            rest = uri[len("package://"):]
            pkg, _, sub = rest.partition("/")
            for d in _package_dirs(pkg):
                cand = d / sub
                if cand.exists():
                    return cand
            return self._search(rest, self._model_dirs(base_dir), uri, at,
                                f"source the ROS workspace that holds package {pkg!r} (AMENT_PREFIX_PATH) or put "
                                f"its parent folder on GZ_SIM_RESOURCE_PATH")
        if low.startswith("file://"):
            uri_path = uri[len("file://"):]
        elif "://" in uri:
            raise SdfError(f"{at}: unknown URI scheme in {uri!r} (model://, package://, file://, Fuel https:// "
                           f"or a path)")
        else:
            uri_path = uri
        p = Path(unquote(uri_path))
        if p.is_absolute():
            if p.exists():
                return p
            raise SdfError(f"{at}: file {uri!r} not found")
        dirs = [Path(base_dir), self.world_dir] + resource_dirs()
        return self._search(str(p), dirs, uri, at, "the path is relative to the file that names it")

    def _model_dirs(self, base_dir: Path) -> list[Path]:
        return resource_dirs([Path(base_dir), self.world_dir, CLASSIC_MODEL_DIR])

    @staticmethod
    def _search(rest: str, dirs: list[Path], uri: str, at: str, advice: str) -> Path:
        seen = []
        for d in dirs:
            if d in seen:
                continue
            seen.append(d)
            cand = d / rest
            if cand.exists():
                return cand
        raise SdfError(f"{at}: cannot find {uri!r}: searched {[str(d) for d in seen]} ({advice})")

    @staticmethod
    def _fuel(uri: str, at: str) -> Path:
        folder, sub, looked = fuel_model_dir(uri)
        if not looked:
            raise SdfError(f"{at}: network URI {uri!r} is not a Fuel model URL and is never fetched: download "
                           f"the file and give its path")
        if folder is None:
            raise SdfError(f"{at}: Fuel model {uri!r} is not in the local Fuel cache (looked in "
                           f"{[str(p) for p in looked]}); URIs are never fetched from the network: download it "
                           f"once with `gz fuel download -u \"{uri}\"` (or set GZ_FUEL_CACHE_PATH to a cache that "
                           f"holds it)")
        target = folder / sub if sub else folder
        if not target.exists():
            raise SdfError(f"{at}: {uri!r}: file {sub!r} not found in the cached model {folder}")
        return target


def _version_key(v: str):
    try:
        return tuple(int(x) for x in v.split("."))
    except ValueError:
        return (0,)


def model_sdf_path(model_dir: Path, el=None, file="<sdf>") -> Path:
    """The SDF file of a model folder: from ``model.config`` (highest ``<sdf version>``) or ``model.sdf``."""
    at = where(el, file) if el is not None else str(file)
    if model_dir.is_file():
        return model_dir
    cfg = model_dir / "model.config"
    if cfg.is_file():
        root = parse_xml(cfg)
        entries = [(s.get("version", "0"), (s.text or "").strip()) for s in root.iter("sdf") if (s.text or "").strip()]
        if entries:
            entries.sort(key=lambda e: _version_key(e[0]))
            p = model_dir / entries[-1][1]
            if not p.is_file():
                raise SdfError(f"{cfg}: names SDF file {entries[-1][1]!r} which does not exist")
            return p
    p = model_dir / "model.sdf"
    if p.is_file():
        return p
    raise SdfError(f"{at}: model folder {model_dir} has neither model.config with <sdf> nor model.sdf")
