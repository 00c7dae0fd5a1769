"""Check a ROS 2 Python launch file without ROS 2's `launch` (it has no wheel here).

    python -m rftgls_ros.launch_check FILE.launch.py [name:=value ...]

The file is evaluated by rftgls_ros.launch_model (stand-ins of the launch classes; nothing is
started) down to each program's command line, built by launch_ros's rules (`--ros-args
-r __node:=... --params-file <temporary YAML> ...`). Then, for every program:

- the executable exists where `ros2 run` looks: <prefix>/lib/<package>/<executable> for a
  prefix on AMENT_PREFIX_PATH that registers the package in the ament index;
- its own argument parsing accepts that command line: rcl parses the ROS arguments (remaps,
  parameter files) in a private rclpy context, with DDS discovery off (see `_init`); a
  program that is not an rclpy node class (the simulator, the bag replay) parses the rest
  with its module's `parse_args`;
- a node (the rclpy Node subclass behind the executable's entry point) is built in that
  context, so it takes its name, namespace and parameters from the command line exactly as
  it would under `ros2 launch`: a value of the wrong type (an integer for a float parameter)
  or out of range is refused here;
- every parameter it is given is declared by the node;
- every remapping's source is a topic or service name the node uses.

Included launch files are checked with the arguments the includer passes. Launch arguments
without a default must be given (a test passes them). Exit status 1 and one line per problem.
"""
from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import inspect
import io
import os
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

from rftgls_conventions import one_line
from rftgls_conventions.safe_read import load_yaml
from rftgls_node_base.dds_loopback import discovery_off

from .launch_model import Parsed, Process, executable_path, parse, program_argv, share_dir

__all__ = ['Parsed', 'Process', 'check', 'check_node', 'parse', 'share_dir']


def entry_module(package: str, executable: str):
    """The module of the executable's console-script entry point."""
    for ep in importlib.metadata.entry_points(group='console_scripts', name=executable):
        module_name = ep.value.split(':')[0]
        if module_name.split('.')[0] == package:
            return importlib.import_module(module_name)
    raise LookupError(f'no console script {executable!r} of package {package!r}')


def node_class(module):
    """The rclpy Node subclass defined in the module, or None (a program that is not one)."""
    from rclpy.node import Node as RclpyNode
    classes = [c for _, c in inspect.getmembers(module, inspect.isclass)
               if issubclass(c, RclpyNode) and c.__module__ == module.__name__]
    return classes[0] if classes else None


def file_sections(params: Path, node_name: str) -> list[dict[str, Any]]:
    """The ``ros__parameters`` sections of a ROS 2 parameter file that apply to node_name
    (``/**``, the bare name, ``/name``, ``/**/name``), in that order (later wins)."""
    doc = load_yaml(params, 'params', 'parameter file') or {}
    return [doc[k]['ros__parameters'] for k in ('/**', node_name, '/' + node_name,
                                                '/**/' + node_name)
            if k in doc and 'ros__parameters' in (doc[k] or {})]


def parameter_values(p: Process, node_name: str) -> tuple[dict[str, Any], list[str]]:
    """The parameters a Node action sets for `node_name`, in order (later wins), and the
    problems with its files."""
    values: dict[str, Any] = {}
    problems = []
    for params in p.parameters:
        if isinstance(params, dict):
            values.update(params)
            continue
        if not params.is_file():
            problems.append(f'{p.source}: {p.executable}: parameter file {params} '
                            'does not exist')
            continue
        sections = file_sections(params, node_name)
        if not sections:
            problems.append(f'{p.source}: {p.executable}: {params.name} has no section for '
                            f'node {node_name!r}')
        for s in sections:
            values.update(s)
    return values, problems


def _full(name: str, node_name: str, namespace: str) -> str:
    ns = '/' + namespace.strip('/') if namespace.strip('/') else ''
    if name.startswith('~'):
        return f'{ns}/{node_name}{name[1:]}'
    return name if name.startswith('/') else f'{ns}/{name}'


def _own_parsing(module, cmd: list[str], what: str) -> list[str]:
    """A program's own argument parsing (its module's `parse_args`) on the command line."""
    parse_args = getattr(module, 'parse_args', None)
    if parse_args is None:
        return [f'{what}: not an rclpy node and no parse_args(argv) to check its arguments']
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            parse_args(cmd[1:])
    except SystemExit as exc:
        if exc.code not in (0, None):
            return [f'{what}: refuses its command line: {one_line(err.getvalue())}']
    return []


def check_node(p: Process, tmpdir: str | Path | None = None) -> list[str]:
    """Problems of one program of a launch file (see the module doc)."""
    what = f'{p.source}: {p.package}/{p.executable}'
    if executable_path(p.package, p.executable) is None:
        return [f'{what}: no executable lib/{p.package}/{p.executable} on AMENT_PREFIX_PATH']
    try:
        module = entry_module(p.package, p.executable)
    except (LookupError, ImportError) as exc:
        return [f'{what}: {exc}']
    with contextlib.ExitStack() as stack:
        if tmpdir is None:
            tmpdir = stack.enter_context(tempfile.TemporaryDirectory(prefix='launch_check_'))
        if p.prefix and shutil.which(p.prefix[0]) is None:
            return [f'{what}: prefix program {p.prefix[0]!r} not found on PATH']
        cmd = program_argv(p, tmpdir)     # what the program parses (a prefix execs it)
        cls = node_class(module)
        if p.kind != 'node':
            if cls is not None:
                return [f'{what}: an rclpy node started by ExecuteProcess gets no ROS '
                        'arguments (use launch_ros Node)']
            return _own_parsing(module, cmd, what)
        return _check_with_rclpy(p, cmd, module, cls, what)
    return []  # pragma: no cover - ExitStack does not swallow


def _init(cmd: list[str]):
    """A private rclpy context initialised with the command line (rcl parses its ROS
    arguments); raises what rcl raises.

    Its DDS participant discovers no one (discovery range OFF, which rcl reads from the
    environment inside rclpy.init, once): a check needs no peer, and a participant that has
    never heard of another has no discovery callback in flight when the check destroys it.
    One in flight can make Fast DDS 2.14 spin for good inside the participant's deletion
    (docs/design/jazzy-robot.md, "The teardown timer"), and the checker, unlike a node
    program, runs inside a caller (a test, a tool) that no teardown timer may end."""
    import rclpy
    ctx = rclpy.Context()
    with discovery_off():
        rclpy.init(args=cmd, context=ctx, domain_id=int(os.environ.get('ROS_DOMAIN_ID', '0')))
    return ctx


def _without_remaps(cmd: list[str], remaps: list[tuple[str, str]]) -> list[str]:
    """cmd without the `-r FROM:=TO` pairs of the launch file's remappings (the node is then
    built with the names it uses itself, to check each remapping's source against)."""
    rules = {f'{a}:={b}' for a, b in remaps}
    out: list[str] = []
    i = 0
    while i < len(cmd):
        if cmd[i] == '-r' and i + 1 < len(cmd) and cmd[i + 1] in rules:
            i += 2
            continue
        out.append(cmd[i])
        i += 1
    return out


def _check_with_rclpy(p: Process, cmd: list[str], module, cls, what: str) -> list[str]:
    import rclpy
    try:
        rclpy.try_shutdown(context=_init(cmd))
    except Exception as exc:  # noqa: BLE001 - rcl refuses the ROS arguments
        return [f'{what}: rcl refuses its ROS arguments: {one_line(exc)}']
    if cls is None:
        if p.parameters:
            return [f'{what}: not an rclpy node class; it takes no parameters']
        return _own_parsing(module, cmd, what)
    ctx = _init(_without_remaps(cmd, p.remappings))
    node = None
    try:
        try:
            node = cls(context=ctx)   # name, namespace, parameters: from the command line
        except Exception as exc:  # noqa: BLE001 - the node refused these values
            return [f'{what}: refuses its launch parameters: {type(exc).__name__}: '
                    f'{one_line(exc)}']
        values, problems = parameter_values(p, node.get_name())
        declared = set(node.list_parameters([], 0).names)
        for k in sorted(set(values) - declared):
            problems.append(f'{what}: parameter {k!r} is not declared by the node')
        used = {x.topic_name for x in (*node.publishers, *node.subscriptions)}
        used |= {x.srv_name for x in (*node.services, *node.clients)}
        for src, _dst in p.remappings:
            if _full(src, node.get_name(), node.get_namespace()) not in used:
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
    with tempfile.TemporaryDirectory(prefix='launch_check_') as tmp:
        for p in parsed.nodes:
            problems += check_node(p, tmp)
    return problems


def main(argv_: list[str] | None = None) -> int:
    argv_ = sys.argv[1:] if argv_ is None else argv_
    if not argv_ or argv_[0] in ('-h', '--help'):
        print(__doc__.strip().split('\n\n')[1])
        return 0 if argv_ else 2
    args = dict(a.split(':=', 1) for a in argv_[1:])
    problems = check(argv_[0], args)
    for p in problems:
        print(p)
    if not problems:
        print(f'{argv_[0]}: ok')
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
