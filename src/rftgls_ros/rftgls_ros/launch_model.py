"""A ROS 2 Python launch file, evaluated without ROS 2's `launch` (it has no wheel here), down
to the command lines launch would run.

The file runs against small stand-ins of the `launch` / `launch_ros` classes it uses, which
only record their arguments; `parse()` then resolves the substitutions with the launch
arguments and returns one `Process` per Node or ExecuteProcess action (included files too).
`argv()` builds a Process's command line by the rules of launch_ros's Node action (Jazzy,
launch_ros 0.26): the executable, its `arguments`, then `--ros-args`, `-r __node:=NAME` when a
name is given, `-r __ns:=/NS` when a namespace is, one `--params-file` per parameter entry (a
dict becomes a temporary YAML file `{<fully qualified name> or /**: {ros__parameters: ...}}`),
then `-r FROM:=TO` per remapping. Parameter values follow launch_ros's evaluation: a
substituted value is read as YAML (so `sled_mass_kg:=1` is the integer 1) unless wrapped in
`ParameterValue(..., value_type=float)`, which converts it; plain values pass as they are.
An ExecuteProcess runs its `cmd` as given, with no ROS arguments. Either action's `prefix`
(launch's Executable, Jazzy) is resolved to one string, split with `shlex.split` and put in
front of the command; without one, launch uses the `launch-prefix` launch configuration
(`ros2 launch --launch-prefix`, default ''), which this model takes from the arguments given.
A prefix set in the file replaces `launch-prefix`, and `launch-prefix-filter` then does not
apply.

Used by launch_check (checks every program against its command line) and launch_run (starts
the programs, the project's stand-in for `ros2 launch`).
"""
from __future__ import annotations

import os
import runpy
import shlex
import sys
import types
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

STUB_MODULES = ('launch', 'launch.actions', 'launch.substitutions',
                'launch.launch_description_sources', 'launch_ros', 'launch_ros.actions',
                'launch_ros.substitutions', 'launch_ros.parameter_descriptions')


# -- stand-ins of the launch API: they only record their arguments ---------------------------
class _Recorded:
    def __init__(self, *args, **kwargs):
        self.args = args
        self.kwargs = kwargs

    def arg(self, i: int, name: str, default: Any = None) -> Any:
        """Positional argument i or keyword `name`."""
        return self.args[i] if len(self.args) > i else self.kwargs.get(name, default)


class LaunchDescription(_Recorded):
    pass


class DeclareLaunchArgument(_Recorded):
    pass


class IncludeLaunchDescription(_Recorded):
    pass


class PythonLaunchDescriptionSource(_Recorded):
    pass


class LaunchConfiguration(_Recorded):
    pass


class PathJoinSubstitution(_Recorded):
    pass


class TextSubstitution(_Recorded):
    pass


class FindPackageShare(_Recorded):
    pass


class ExecutableInPackage(_Recorded):
    pass


class Node(_Recorded):
    pass


class ExecuteProcess(_Recorded):
    pass


class ParameterValue(_Recorded):
    pass


def _module(name: str, **attrs) -> types.ModuleType:
    m = types.ModuleType(name)
    m.__dict__.update(attrs)

    m.__path__ = []  # type: ignore[attr-defined]  # a package: submodules are the stubs above

    def missing(attr: str):
        if attr.startswith('__'):
            raise AttributeError(attr)
        raise ImportError(f'launch_model: {name}.{attr} is not modelled')
    m.__getattr__ = missing  # type: ignore[attr-defined]
    return m


@contextmanager
def stub_launch() -> Iterator[None]:
    """Put the stand-ins in sys.modules for the duration (the real modules, if any, return)."""
    saved = {n: sys.modules.get(n) for n in STUB_MODULES}
    sys.modules.update({
        'launch': _module('launch', LaunchDescription=LaunchDescription),
        'launch.actions': _module('launch.actions', DeclareLaunchArgument=DeclareLaunchArgument,
                                  IncludeLaunchDescription=IncludeLaunchDescription,
                                  ExecuteProcess=ExecuteProcess),
        'launch.substitutions': _module('launch.substitutions',
                                        LaunchConfiguration=LaunchConfiguration,
                                        PathJoinSubstitution=PathJoinSubstitution,
                                        TextSubstitution=TextSubstitution),
        'launch.launch_description_sources': _module(
            'launch.launch_description_sources',
            PythonLaunchDescriptionSource=PythonLaunchDescriptionSource),
        'launch_ros': _module('launch_ros'),
        'launch_ros.actions': _module('launch_ros.actions', Node=Node),
        'launch_ros.substitutions': _module('launch_ros.substitutions',
                                            FindPackageShare=FindPackageShare,
                                            ExecutableInPackage=ExecutableInPackage),
        'launch_ros.parameter_descriptions': _module('launch_ros.parameter_descriptions',
                                                     ParameterValue=ParameterValue),
    })
    try:
        yield
    finally:
        for n, m in saved.items():
            if m is None:
                sys.modules.pop(n, None)
            else:
                sys.modules[n] = m


# -- the ament index, as `ros2 run` and FindPackageShare use it ------------------------------
def _prefixes() -> list[Path]:
    return [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]


def _registers(prefix: Path, package: str) -> bool:
    return (prefix / 'share/ament_index/resource_index/packages' / package).is_file()


def share_dir(package: str) -> Path | None:
    """<prefix>/share/<package> of the first ament prefix that registers the package."""
    for prefix in _prefixes():
        if _registers(prefix, package):
            return prefix / 'share' / package
    return None


def executable_path(package: str, executable: str) -> Path | None:
    """Where `ros2 run` finds it: <prefix>/lib/<package>/<executable> (tools/ros2 does the
    same lookup)."""
    for prefix in _prefixes():
        exe = prefix / 'lib' / package / executable
        if _registers(prefix, package) and exe.is_file() and os.access(exe, os.X_OK):
            return exe
    return None


# -- evaluation -------------------------------------------------------------------------------
@dataclass
class Process:
    """One Node (kind 'node') or ExecuteProcess (kind 'process') action, resolved."""

    source: str
    kind: str
    package: str
    executable: str
    name: str | None = None
    namespace: str | None = None
    parameters: list[Any] = field(default_factory=list)   # dicts (evaluated) and Paths
    remappings: list[tuple[str, str]] = field(default_factory=list)
    arguments: list[str] = field(default_factory=list)
    prefix: list[str] = field(default_factory=list)        # shlex-split, before the command


@dataclass
class Parsed:
    nodes: list[Process] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


def resolve(value: Any, args: dict[str, str]) -> Any:
    """A launch value with its substitutions replaced by strings (lists are concatenated)."""
    if isinstance(value, str | bool | int | float):
        return value
    if isinstance(value, LaunchConfiguration):
        name = value.arg(0, 'variable_name')
        if name in args:
            return args[name]
        default = value.arg(1, 'default')
        if default is None:
            raise KeyError(f'launch argument {name!r} has no value')
        return resolve(default, args)
    if isinstance(value, TextSubstitution):
        return value.arg(0, 'text', '')
    if isinstance(value, PathJoinSubstitution):
        return os.path.join(*[resolve(v, args) for v in value.arg(0, 'substitutions')])
    if isinstance(value, FindPackageShare):
        d = share_dir(resolve(value.arg(0, 'package'), args))
        return str(d) if d else f'<package {value.args[0]} not found>'
    if isinstance(value, ExecutableInPackage):
        pkg, exe = resolve(value.arg(1, 'package'), args), resolve(value.arg(0, 'executable'),
                                                                     args)
        path = executable_path(pkg, exe)
        if path is None:
            raise KeyError(f'no executable lib/{pkg}/{exe} on AMENT_PREFIX_PATH')
        return str(path)
    if isinstance(value, list | tuple):
        return ''.join(str(resolve(v, args)) for v in value)
    raise TypeError(f'launch_model: cannot evaluate {type(value).__name__}')


def _is_substitution(value: Any) -> bool:
    return isinstance(value, _Recorded) or (
        isinstance(value, list | tuple) and any(isinstance(v, _Recorded) for v in value))


def coerce(text: str, value_type: Any) -> Any:
    """launch's coerce_to_type: int/float by their constructors, str as it is, bool and
    no type by YAML rules (ValueError when the result is not of the type)."""
    if value_type in (int, float):
        return value_type(text)
    if value_type is str:
        return text
    out = yaml.safe_load(text) if text else text
    if value_type is bool and not isinstance(out, bool):
        raise ValueError(f'{text!r} is not a bool')
    return out


def parameter_value(value: Any, args: dict[str, str]) -> Any:
    """One value of a parameter dict, evaluated as launch_ros does."""
    if isinstance(value, ParameterValue):
        inner, vtype = value.arg(0, 'value'), value.kwargs.get('value_type')
        if _is_substitution(inner):
            return coerce(resolve(inner, args), vtype)
        if vtype is not None and not isinstance(inner, vtype):
            raise TypeError(f'ParameterValue {inner!r} is not a {vtype.__name__}')
        return inner
    if _is_substitution(value):
        text = resolve(value, args)
        loaded = yaml.safe_load(text if text else "''")
        if not isinstance(loaded, bool | int | float | str | list):
            raise TypeError(f'parameter value {text!r} is not a scalar or a list')
        return loaded
    if isinstance(value, list | tuple):
        return [parameter_value(v, args) for v in value]
    return value


def _flatten(d: dict, args: dict[str, str], prefix: str = '') -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = prefix + str(resolve(k, args))
        if isinstance(v, dict):
            out.update(_flatten(v, args, key + '.'))
        else:
            out[key] = parameter_value(v, args)
    return out


def parse(path: str | Path, args: dict[str, str] | None = None) -> Parsed:
    """Run a launch file against the stand-ins; its processes (and those of included files)."""
    out = Parsed()
    _parse(Path(path), dict(args or {}), out)
    return out


def _arg_name(e: DeclareLaunchArgument) -> str:
    return e.arg(0, 'name')


def _parse(path: Path, given: dict[str, str], out: Parsed) -> None:
    where = path.name
    try:
        with stub_launch():
            ld = runpy.run_path(str(path))['generate_launch_description']()
    except Exception as exc:  # noqa: BLE001 - any failure is the finding
        out.problems.append(f'{where}: does not evaluate: {type(exc).__name__}: {exc}')
        return
    if not isinstance(ld, LaunchDescription):
        out.problems.append(f'{where}: generate_launch_description() returned '
                            f'{type(ld).__name__}, not a LaunchDescription')
        return
    args = dict(given)
    entities = list(ld.arg(0, 'initial_entities', []))
    declared = [e for e in entities if isinstance(e, DeclareLaunchArgument)]
    for e in declared:
        if _arg_name(e) not in args:
            default = e.kwargs.get('default_value')
            if default is None:
                out.problems.append(f'{where}: launch argument {_arg_name(e)!r} has no default '
                                    'and was not given')
                continue
            args[_arg_name(e)] = resolve(default, args)
    # launch-prefix is launch's own configuration (`ros2 launch --launch-prefix`), seen by
    # every file, included ones too.
    for name in sorted(set(given) - {_arg_name(e) for e in declared} - {'launch-prefix'}):
        out.problems.append(f'{where}: argument {name!r} is not declared')
    for e in entities:
        try:
            if isinstance(e, Node):
                out.nodes.append(_node(where, e, args))
            elif isinstance(e, ExecuteProcess):
                out.nodes.append(_process(where, e, args))
            elif isinstance(e, IncludeLaunchDescription):
                src = e.arg(0, 'launch_description_source')
                sub = Path(resolve(src.arg(0, 'launch_file_path'), args))
                passed = {resolve(k, args): resolve(v, args)
                          for k, v in (e.kwargs.get('launch_arguments') or [])}
                if 'launch-prefix' in args:
                    passed.setdefault('launch-prefix', args['launch-prefix'])
                if not sub.is_file():
                    out.problems.append(f'{where}: included file {sub} does not exist')
                else:
                    _parse(sub, passed, out)
            elif not isinstance(e, DeclareLaunchArgument):
                out.problems.append(f'{where}: {type(e).__name__} is not modelled')
        except (KeyError, TypeError, ValueError) as exc:
            out.problems.append(f'{where}: {exc.args[0] if exc.args else exc}')


def _prefix(e: _Recorded, args: dict[str, str]) -> list[str]:
    """The action's prefix as launch's Executable builds it: the substituted string, split
    like a shell would (no prefix: the `launch-prefix` configuration, default '')."""
    given = e.kwargs.get('prefix')
    text = args.get('launch-prefix', '') if given is None else resolve(given, args)
    return shlex.split(str(text))


def _node(where: str, e: Node, args: dict[str, str]) -> Process:
    kw = e.kwargs
    params: list[Any] = []
    for p in kw.get('parameters') or []:
        params.append(_flatten(p, args) if isinstance(p, dict) else Path(resolve(p, args)))
    return Process(
        source=where, kind='node', package=resolve(kw['package'], args),
        executable=resolve(kw['executable'], args),
        name=resolve(kw['name'], args) if kw.get('name') is not None else None,
        namespace=resolve(kw['namespace'], args) if kw.get('namespace') is not None else None,
        parameters=params,
        remappings=[(resolve(a, args), resolve(b, args)) for a, b in kw.get('remappings') or []],
        arguments=[str(resolve(a, args)) for a in kw.get('arguments') or []],
        prefix=_prefix(e, args))


def _process(where: str, e: ExecuteProcess, args: dict[str, str]) -> Process:
    cmd = list(e.kwargs['cmd'])
    if not cmd or not isinstance(cmd[0], ExecutableInPackage):
        raise TypeError('ExecuteProcess: only cmd=[ExecutableInPackage(...), ...] is modelled')
    first = cmd[0]
    return Process(source=where, kind='process', package=resolve(first.arg(1, 'package'), args),
                   executable=resolve(first.arg(0, 'executable'), args),
                   arguments=[str(resolve(a, args)) for a in cmd[1:]], prefix=_prefix(e, args))


# -- command lines ------------------------------------------------------------------------------
def _absolute(ns: str) -> str:
    ns = ns.rstrip('/') or '/'
    return ns if ns.startswith('/') else '/' + ns


def fully_qualified_name(p: Process) -> str | None:
    """'/ns/name' when both name and namespace are given (launch_ros's params file key),
    else None (the file then uses '/**')."""
    if p.name is None or p.namespace is None:
        return None
    ns = _absolute(p.namespace)
    return (ns if ns != '/' else '') + '/' + p.name


def argv(p: Process, tmpdir: str | Path) -> list[str]:
    """The command line launch would run for `p`: its prefix, then `program_argv`."""
    return [*p.prefix, *program_argv(p, tmpdir)]


def program_argv(p: Process, tmpdir: str | Path) -> list[str]:
    """The program's own command line (see the module doc), without the prefix. Dict
    parameters are written to YAML files in tmpdir. KeyError when the executable is not
    installed."""
    exe = executable_path(p.package, p.executable)
    if exe is None:
        raise KeyError(f'no executable lib/{p.package}/{p.executable} on AMENT_PREFIX_PATH')
    cmd = [str(exe), *p.arguments]
    if p.kind != 'node':
        return cmd
    cmd.append('--ros-args')
    if p.name is not None:
        cmd += ['-r', f'__node:={p.name}']
    if p.namespace is not None:
        cmd += ['-r', f'__ns:={_absolute(p.namespace)}']
    for i, params in enumerate(p.parameters):
        if isinstance(params, dict):
            f = Path(tmpdir) / f'launch_params_{p.executable}_{os.getpid()}_{i}.yaml'
            key = fully_qualified_name(p) or '/**'
            f.write_text(yaml.dump({key: {'ros__parameters': params}},
                                   default_flow_style=False))
            cmd += ['--params-file', str(f)]
        elif Path(params).is_file():          # launch_ros skips a missing file (a warning)
            cmd += ['--params-file', str(params)]
    for src, dst in p.remappings:
        cmd += ['-r', f'{src}:={dst}']
    return cmd
