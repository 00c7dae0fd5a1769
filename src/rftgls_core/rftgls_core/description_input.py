"""An anchor description as untrusted input: the files it may read, the shape of its YAML.

A description (YAML + URDF or xacro + meshes) is input a person hands to a tool, so what it
can make the tool read is bounded and its YAML is checked before any field is used
(docs/design/safe-io.md, "Descriptions"):

- Allow-list: every file it names (the URDF, xacro includes, YAML loaded by xacro, meshes)
  must lie, after resolving `..` and symlinks, inside the description's own folder or the
  `share` folder of an installed package (each prefix of AMENT_PREFIX_PATH, where `$(find
  pkg)` points). Anything else is refused before it is opened, and the refusal never shows
  the file's content.
- No environment: xacro's `$(env ...)`, `$(optenv ...)` and the eval forms `env()`/`optenv()`
  are refused; a description means the same on every machine.
- Every file goes through safe_read: regular files only, a size limit per kind.
- Include patterns (globs) are refused: each file is named.
- The YAML's fields have the types the loader needs (`check_document`): a `state:` given as a
  string, a range of null, a point of text are one line naming the field, never a crash.

xacro keeps its state in module globals, so expansions run one at a time (a lock) with the
sandbox patched in and removed again; its own messages to stderr are kept off the terminal
(the error, if any, is one line).
"""
from __future__ import annotations

import contextlib
import io
import os
import threading
from collections.abc import Iterator
from pathlib import Path

from rftgls_conventions.safe_read import InputFileError, check_regular, parse_yaml, read_bytes
from rftgls_conventions.safe_read import read_text as _read_text

_XACRO_LOCK = threading.Lock()


class SourceError(ValueError):
    """A description file outside the allow-list, unreadable, an expansion refused, or a
    YAML field of the wrong type. One line naming the file."""


def installed_share_folders() -> list[Path]:
    """The `share` folder of every prefix in AMENT_PREFIX_PATH (the installed packages)."""
    out = []
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix and (Path(prefix) / 'share').is_dir():
            out.append(Path(prefix) / 'share')
    return out


def allowed_roots(description_folder: str | os.PathLike) -> tuple[Path, ...]:
    """The folders a description in `description_folder` may read from (real paths)."""
    roots = [Path(description_folder)] + installed_share_folders()
    return tuple(Path(os.path.realpath(r)) for r in roots)


def check_allowed(path: str | os.PathLike, roots: tuple[Path, ...], what: str) -> Path:
    """path when its real path lies inside one of `roots`; SourceError otherwise (naming the
    path as written, never its content)."""
    real = Path(os.path.realpath(path))
    for root in roots:
        if real == root or root in real.parents:
            return Path(path)
    raise SourceError(f'{path}: a {what} outside the description\'s folder and the installed '
                      'packages is not read')


def read_source(path: str | os.PathLike, roots: tuple[Path, ...], kind: str, what: str) -> bytes:
    """The bytes of an allowed, regular file within the size limit of `kind`."""
    check_allowed(path, roots, what)
    try:
        return read_bytes(path, kind, what)
    except InputFileError as exc:
        raise SourceError(str(exc)) from None


def mesh_path(filename: str, urdf: Path, roots: tuple[Path, ...]) -> Path:
    """The mesh file a URDF names, checked against the allow-list: relative to the URDF's
    folder, an absolute or `file://` path, or `package://PKG/REST` = <prefix>/share/PKG/REST
    for the first prefix on AMENT_PREFIX_PATH that has it (SourceError when none does)."""
    if filename.startswith('package://'):
        pkg, _, rest = filename[len('package://'):].partition('/')
        for share in installed_share_folders():
            candidate = share / pkg / rest
            if candidate.is_file():
                return check_allowed(candidate, roots, 'mesh')
        raise SourceError(f'{urdf}: mesh {filename}: package {pkg!r} is not on '
                          'AMENT_PREFIX_PATH (source the workspace)')
    fname = filename[len('file://'):] if filename.startswith('file://') else filename
    file = Path(fname) if Path(fname).is_absolute() else urdf.parent / fname
    return check_allowed(file, roots, 'mesh')


def urdf_bytes(path: str | os.PathLike, roots: tuple[Path, ...] | None = None) -> bytes:
    """The URDF XML of `path`: the file's bytes, or for a `*.xacro` file the document xacro
    expands it to inside the sandbox (the root element only: xacro's banner comment names the
    file, which would make a copy elsewhere a different description). roots: the allow-list
    (default: the file's own folder and the installed packages)."""
    path = Path(path)
    roots = allowed_roots(path.parent) if roots is None else roots
    if path.suffix != '.xacro':
        return read_source(path, roots, 'urdf', 'URDF')
    check_allowed(path, roots, 'xacro file')
    try:
        check_regular(path, 'urdf', 'xacro file')
    except InputFileError as exc:
        raise SourceError(str(exc)) from None
    try:
        import xacro
    except ImportError:  # pragma: no cover - a dependency of rftgls_core
        raise SourceError(f'{path}: expanding xacro needs the xacro package') from None
    refused: list[str] = []
    try:
        with _sandbox(xacro, roots, refused), contextlib.redirect_stderr(io.StringIO()):
            doc = xacro.process_file(str(path))
    except Exception as exc:  # noqa: BLE001 - xacro raises its own and parser errors
        if refused:
            raise SourceError(f'{path}: {refused[0]}') from None
        raise SourceError(f'{path}: xacro cannot expand it ({type(exc).__name__}: '
                          f'{" ".join(str(exc).split()) or "no message"})') from None
    return doc.documentElement.toxml().encode('utf-8')


@contextlib.contextmanager
def _sandbox(xacro, roots: tuple[Path, ...], refused: list[str]) -> Iterator[None]:
    """xacro with file access through the allow-list and no environment (see module doc);
    every refusal is recorded in `refused` (xacro wraps the exception in its own)."""
    from xacro import substitution_args as sa

    def refuse(message: str):
        refused.append(message)
        raise SourceError(message)

    def no_env(*_args, **_kwargs):
        refuse('$(env ...) and $(optenv ...) are refused: a description reads no environment '
               'variables')

    original_abs = xacro.abs_filename_spec

    def allowed_abs(spec: str) -> str:
        name = original_abs(spec)
        if any(c in name for c in '*?['):
            refuse(f'include pattern {spec!r} refused: name each file')
        try:
            check_allowed(name, roots, 'file named by the xacro')
            check_regular(name, 'urdf', 'file named by the xacro')
        except ValueError as exc:
            refuse(str(exc))
        return name

    def load_yaml(filename: str):
        name = allowed_abs(filename)
        try:
            doc = parse_yaml(_read_text(name, 'description', 'YAML'), name)
        except InputFileError as exc:
            refuse(str(exc))
        return xacro.YamlListWrapper.wrap(doc)

    symbols = xacro._global_symbols
    namespace = symbols.get('xacro')
    patches: list[tuple[object, str, object]] = [
        (xacro, 'abs_filename_spec', allowed_abs), (sa, '_eval_env', no_env),
        (sa, '_eval_optenv', no_env)]
    items: list[tuple[dict, str, object]] = [
        (sa._eval_dict, 'env', no_env), (sa._eval_dict, 'optenv', no_env),
        (symbols, 'load_yaml', load_yaml)]
    if namespace is not None:
        items.append((namespace, 'load_yaml', load_yaml))
    with _XACRO_LOCK:
        saved: list[tuple[object, str, object]] = [(obj, name, getattr(obj, name))
                                                   for obj, name, _ in patches]
        saved_items = [(d, k, dict.get(d, k)) for d, k, _ in items]
        try:
            for obj, name, value in patches:
                setattr(obj, name, value)
            for d, k, value in items:
                dict.__setitem__(d, k, value)
            yield
        finally:
            for obj, name, value in saved:
                setattr(obj, name, value)
            for d, k, value in saved_items:
                dict.__setitem__(d, k, value)


def check_range(path, quantity, values, what: str, error: type = SourceError) -> None:
    """`error` naming the first of `values` outside the physical range of `quantity`
    (quantities.py): a description's masses, origins and scales are input like any other."""
    import numpy as np
    for v in np.ravel(values):
        problem = quantity.violation(float(v))
        if problem:
            raise error(f'{path}: {what}: {problem}')


# ------------------------------------------------------------------------- the YAML's shape
def _number(x) -> bool:
    import math
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _numbers(x, n: int | None = None) -> bool:
    return isinstance(x, list) and (n is None or len(x) == n) and all(_number(v) for v in x)


def check_document(path: str | os.PathLike, doc: object) -> dict:
    """doc when its fields have the types a description needs; SourceError naming the first
    field that does not (values are not quoted). Meanings (units, ranges, joint names) are
    checked by the loader afterwards."""
    def need(ok: bool, what: str) -> None:
        if not ok:
            raise SourceError(f'{path}: {what}')
    need(isinstance(doc, dict), 'a description is a mapping with at least `urdf:` and `state:`')
    assert isinstance(doc, dict)
    need(isinstance(doc.get('urdf'), str) and bool(doc['urdf'].strip()),
         '`urdf:` must name a URDF or xacro file')
    for key in ('name', 'tether_link', 'medium', 'symmetry'):
        need(doc.get(key) is None or isinstance(doc[key], str), f'`{key}:` must be text')
    need(doc.get('char_length_m') is None or (_number(doc['char_length_m'])
                                              and doc['char_length_m'] > 0),
         '`char_length_m:` must be a positive number (m)')
    state = doc.get('state')
    need(isinstance(state, list) and len(state) > 0,
         '`state:` must be a list of state variables ({name, unit, physical, ...})')
    assert isinstance(state, list)
    for i, item in enumerate(state):
        need(isinstance(item, dict) and isinstance(item.get('name'), str),
             f'state variable {i + 1} must be a mapping with a `name:`')
        for key in ('unit',):
            need(item.get(key) is None or isinstance(item[key], str),
                 f'state variable {i + 1}: `{key}:` must be text')
        phys = item.get('physical')
        need(phys is None or not isinstance(phys, list) or _numbers(phys),
             f'state variable {i + 1}: `physical:` must be two finite numbers')
        mr = item.get('map')
        need(mr is None or not isinstance(mr, list) or (
            len(mr) == 3 and _number(mr[0]) and _number(mr[1]) and isinstance(mr[2], int)
            and not isinstance(mr[2], bool) and 2 <= mr[2] <= 10_000),
            f'state variable {i + 1}: `map:` must be [start, stop, count], count 2..10000')
        joints = item.get('joints')
        need(joints is None or (isinstance(joints, list)
                                and all(isinstance(j, str) for j in joints)),
             f'state variable {i + 1}: `joints:` must be a list of joint names')
    bp = doc.get('base_pose')
    need(bp is None or (isinstance(bp, dict) and all(
        bp.get(k) is None or isinstance(bp[k], str) for k in ('height', 'pitch'))),
        '`base_pose:` must map height and pitch to state variable names')
    ps = doc.get('pull_scale')
    need(ps is None or (isinstance(ps, dict) and all(
        (isinstance(v, list) and all(isinstance(x, str) for x in v)) if k == 'links'
        else _numbers(v, 3) for k, v in ps.items())),
        '`pull_scale:` must map pulls to three numbers and `links:` to link names')
    sp = doc.get('surface_points')
    need(sp is None or (isinstance(sp, list) and all(_numbers(p, 3) for p in sp)),
         '`surface_points:` must be a list of [x, y, z] points of base_link, m')
    return doc
