"""Check a ROS 2 Python launch file without ROS 2's `launch` (it has no wheel here).

    python -m rftgls_ros.launch_check FILE.launch.py [name:=value ...]

The file runs against small stand-ins of the `launch` / `launch_ros` classes it uses
(LaunchDescription, DeclareLaunchArgument, IncludeLaunchDescription, LaunchConfiguration,
PathJoinSubstitution, FindPackageShare, Node), which only record what they are given; nothing
is started. Then, for every Node:

- the executable exists where `ros2 run` looks: <prefix>/lib/<package>/<executable> for a
  prefix on AMENT_PREFIX_PATH that registers the package in the ament index;
- every parameter (YAML files: the section of the node's name or `/**`; dicts) is declared by
  the node. The node class behind the executable (its console-script entry point) is built in
  a private rclpy context with those values, which also checks that it accepts them;
- every remapping's source is a topic or service name the node uses;
- an executable that is not an rclpy node (the simulator, a replay tool) takes no parameters
  or remappings.

Included launch files are checked with the arguments the includer passes. Launch arguments
without a default must be given (a test passes them). Exit status 1 and one line per problem.
"""
from __future__ import annotations

import importlib
import importlib.metadata
import inspect
import os
import runpy
import sys
import types
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from rftgls_conventions import one_line
from rftgls_conventions.safe_read import load_yaml
from rftgls_node_base.dds_loopback import during_init

STUB_MODULES = ('launch', 'launch.actions', 'launch.substitutions',
                'launch.launch_description_sources', 'launch_ros', 'launch_ros.actions',
                'launch_ros.substitutions')


# -- stand-ins of the launch API: they only record their arguments ---------------------------
class _Recorded:
    def __init__(self, *args, **kwargs):
        self.args = args
        self.kwargs = kwargs


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


class Node(_Recorded):
    pass


def _module(name: str, **attrs) -> types.ModuleType:
    m = types.ModuleType(name)
    m.__dict__.update(attrs)

    m.__path__ = []  # type: ignore[attr-defined]  # a package: submodules are the stubs above

    def missing(attr: str):
        if attr.startswith('__'):
            raise AttributeError(attr)
        raise ImportError(f'launch_check: {name}.{attr} is not modelled by the checker')
    m.__getattr__ = missing  # type: ignore[attr-defined]
    return m


@contextmanager
def stub_launch() -> Iterator[None]:
    """Put the stand-ins in sys.modules for the duration (the real modules, if any, return)."""
    saved = {n: sys.modules.get(n) for n in STUB_MODULES}
    sys.modules.update({
        'launch': _module('launch', LaunchDescription=LaunchDescription),
        'launch.actions': _module('launch.actions', DeclareLaunchArgument=DeclareLaunchArgument,
                                  IncludeLaunchDescription=IncludeLaunchDescription),
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
                                            FindPackageShare=FindPackageShare),
    })
    try:
        yield
    finally:
        for n, m in saved.items():
            if m is None:
                sys.modules.pop(n, None)
            else:
                sys.modules[n] = m


# -- evaluation ---------------------------------------------------------------------------------
@dataclass
class NodeEntry:
    """One Node action with its substitutions resolved."""

    source: str
    package: str
    executable: str
    name: str | None
    namespace: str
    parameters: list[Any]
    remappings: list[tuple[str, str]]
    arguments: list[str]


@dataclass
class Parsed:
    nodes: list[NodeEntry] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


def share_dir(package: str) -> Path | None:
    """<prefix>/share/<package> of the first ament prefix that registers the package."""
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if prefix and (Path(prefix) / 'share/ament_index/resource_index/packages'
                       / package).is_file():
            return Path(prefix) / 'share' / package
    return None


def resolve(value: Any, args: dict[str, str], from_subst: list[bool] | None = None) -> Any:
    """A launch value with its substitutions replaced by strings (lists are concatenated)."""
    if isinstance(value, str | bool | int | float):
        return value
    if from_subst is not None:
        from_subst.append(True)
    if isinstance(value, LaunchConfiguration):
        name = value.args[0] if value.args else value.kwargs['variable_name']
        if name in args:
            return args[name]
        default = value.kwargs.get('default', value.args[1] if len(value.args) > 1 else None)
        if default is None:
            raise KeyError(f'launch argument {name!r} has no value')
        return resolve(default, args)
    if isinstance(value, TextSubstitution):
        return value.kwargs.get('text', value.args[0] if value.args else '')
    if isinstance(value, PathJoinSubstitution):
        return os.path.join(*[resolve(v, args) for v in value.args[0]])
    if isinstance(value, FindPackageShare):
        d = share_dir(resolve(value.args[0], args))
        return str(d) if d else f'<package {value.args[0]} not found>'
    if isinstance(value, list | tuple):
        return ''.join(resolve(v, args) for v in value)
    raise TypeError(f'launch_check: cannot evaluate {type(value).__name__}')


def parse(path: str | Path, args: dict[str, str] | None = None) -> Parsed:
    """Run a launch file against the stand-ins; its nodes (and those of included files)."""
    out = Parsed()
    _parse(Path(path), dict(args or {}), out)
    return out


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
    entities = list(ld.args[0] if ld.args else ld.kwargs.get('initial_entities', []))
    for e in entities:
        if isinstance(e, DeclareLaunchArgument):
            name = e.args[0] if e.args else e.kwargs['name']
            if name not in args:
                default = e.kwargs.get('default_value')
                if default is None:
                    out.problems.append(f'{where}: launch argument {name!r} has no default '
                                        'and was not given')
                    continue
                args[name] = resolve(default, args)
    unknown = set(given) - {(e.args[0] if e.args else e.kwargs['name']) for e in entities
                            if isinstance(e, DeclareLaunchArgument)}
    for name in sorted(unknown):
        out.problems.append(f'{where}: argument {name!r} is not declared')
    for e in entities:
        try:
            if isinstance(e, Node):
                out.nodes.append(_node(where, e, args))
            elif isinstance(e, IncludeLaunchDescription):
                src = e.args[0] if e.args else e.kwargs['launch_description_source']
                sub = Path(resolve(src.args[0], args))
                passed = {resolve(k, args): resolve(v, args)
                          for k, v in (e.kwargs.get('launch_arguments') or [])}
                if not sub.is_file():
                    out.problems.append(f'{where}: included file {sub} does not exist')
                else:
                    _parse(sub, passed, out)
            elif not isinstance(e, DeclareLaunchArgument):
                out.problems.append(f'{where}: {type(e).__name__} is not checked')
        except KeyError as exc:
            out.problems.append(f'{where}: {exc.args[0]}')


def _node(where: str, e: Node, args: dict[str, str]) -> NodeEntry:
    kw = e.kwargs
    params: list[Any] = []
    for p in kw.get('parameters') or []:
        if isinstance(p, dict):
            d = {}
            for k, v in p.items():
                flag: list[bool] = []
                value = resolve(v, args, flag)
                # launch_ros reads a substituted value as YAML ('0.4' -> 0.4), like -p on the CLI
                d[resolve(k, args)] = yaml.safe_load(value) if flag and isinstance(value, str) \
                    else value
            params.append(d)
        else:
            params.append(Path(resolve(p, args)))
    return NodeEntry(
        source=where, package=resolve(kw['package'], args),
        executable=resolve(kw['executable'], args),
        name=resolve(kw['name'], args) if kw.get('name') is not None else None,
        namespace=resolve(kw.get('namespace') or '', args),
        parameters=params,
        remappings=[(resolve(a, args), resolve(b, args)) for a, b in kw.get('remappings') or []],
        arguments=[resolve(a, args) for a in kw.get('arguments') or []])


# -- checks against the installed workspace and the node classes --------------------------------
def executable_path(package: str, executable: str) -> Path | None:
    """Where `ros2 run` finds it (tools/ros2 does the same lookup)."""
    for prefix in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep):
        if not prefix or not (Path(prefix) / 'share/ament_index/resource_index/packages'
                              / package).is_file():
            continue
        exe = Path(prefix) / 'lib' / package / executable
        if exe.is_file() and os.access(exe, os.X_OK):
            return exe
    return None


def node_class(package: str, executable: str):
    """The rclpy Node subclass defined in the module of the executable's entry point, or None
    (not a node: a plain program)."""
    from rclpy.node import Node as RclpyNode
    for ep in importlib.metadata.entry_points(group='console_scripts', name=executable):
        module_name = ep.value.split(':')[0]
        if module_name.split('.')[0] != package:
            continue
        module = importlib.import_module(module_name)
        classes = [c for _, c in inspect.getmembers(module, inspect.isclass)
                   if issubclass(c, RclpyNode) and c.__module__ == module.__name__]
        return classes[0] if classes else None
    raise LookupError(f'no console script {executable!r} of package {package!r}')


def parameter_values(entry: NodeEntry, node_name: str) -> tuple[dict[str, Any], list[str]]:
    """The parameters a Node action sets, in order (later wins), and problems with files."""
    values: dict[str, Any] = {}
    problems = []
    for p in entry.parameters:
        if isinstance(p, dict):
            values.update(p)
            continue
        if not p.is_file():
            problems.append(f'{entry.source}: {entry.executable}: parameter file {p} '
                            'does not exist')
            continue
        doc = load_yaml(p, 'params', 'parameter file') or {}
        sections = [doc[k]['ros__parameters'] for k in ('/**', node_name, '/' + node_name,
                                                                '/**/' + node_name)
                    if k in doc and 'ros__parameters' in (doc[k] or {})]
        if not sections:
            problems.append(f'{entry.source}: {entry.executable}: {p.name} has no section for '
                            f'node {node_name!r}')
        for s in sections:
            values.update(s)
    return values, problems


def _full(name: str, node_name: str, namespace: str) -> str:
    ns = '/' + namespace.strip('/') if namespace.strip('/') else ''
    if name.startswith('~'):
        return f'{ns}/{node_name}{name[1:]}'
    return name if name.startswith('/') else f'{ns}/{name}'


def check_node(entry: NodeEntry) -> list[str]:
    """Problems of one Node action (see the module doc)."""
    what = f'{entry.source}: {entry.package}/{entry.executable}'
    if executable_path(entry.package, entry.executable) is None:
        return [f'{what}: no executable lib/{entry.package}/{entry.executable} on '
                'AMENT_PREFIX_PATH']
    try:
        cls = node_class(entry.package, entry.executable)
    except (LookupError, ImportError) as exc:
        return [f'{what}: {exc}']
    if cls is None:
        if entry.parameters or entry.remappings or entry.name:
            return [f'{what}: not an rclpy node; it takes no name, parameters or remappings']
        return []
    import rclpy
    from rclpy.parameter import Parameter
    ctx = rclpy.Context()
    with during_init():
        rclpy.init(context=ctx, domain_id=int(os.environ.get('ROS_DOMAIN_ID', '0')))
    node = None
    try:
        probe = cls(context=ctx)      # its own name and declared parameters
        default_name = probe.get_name()
        probe.destroy_node()
        name = entry.name or default_name
        values, problems = parameter_values(entry, name)
        overrides = [Parameter(k, value=v) for k, v in values.items()]
        kwargs: dict[str, Any] = {'context': ctx, 'parameter_overrides': overrides}
        try:
            node = cls(**kwargs)
        except Exception as exc:  # noqa: BLE001 - the node refused these values
            return problems + [f'{what}: refuses its launch parameters: '
                               f'{type(exc).__name__}: {one_line(exc)}']
        declared = set(node.list_parameters([], 0).names)
        for k in sorted(set(values) - declared):
            problems.append(f'{what}: parameter {k!r} is not declared by the node')
        used = {x.topic_name for x in (*node.publishers, *node.subscriptions)}
        used |= {x.srv_name for x in (*node.services, *node.clients)}
        for src, _dst in entry.remappings:
            if _full(src, default_name, '') not in used:
                problems.append(f'{what}: remapping source {src!r} is not a topic or service '
                                'of the node')
        return problems
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def check(path: str | Path, args: dict[str, str] | None = None) -> list[str]:
    """Every problem of a launch file (and the files it includes); [] when it is sound."""
    parsed = parse(path, args)
    problems = list(parsed.problems)
    for entry in parsed.nodes:
        problems += check_node(entry)
    return problems


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] in ('-h', '--help'):
        print(__doc__.strip().split('\n\n')[1])
        return 0 if argv else 2
    args = dict(a.split(':=', 1) for a in argv[1:])
    problems = check(argv[0], args)
    for p in problems:
        print(p)
    if not problems:
        print(f'{argv[0]}: ok')
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
