"""DDS on loopback: how a process of this stack keeps every DDS socket on 127.0.0.1.

The project's rule is `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` for every process that starts
a node. rmw_fastrtps (Jazzy, 8.4.x) implements LOCALHOST by *appending* its own UDPv4
transport with no interface whitelist to whatever the Fast DDS profile configures: that
transport opens send sockets on 0.0.0.0 and on every other interface, so the socket table
shows DDS sockets outside loopback even with a loopback-only profile
(docs/design/capacity-inputs.md, "DDS on loopback").

The repository's profile (ros2_ws/params/fastdds_localhost.xml) does everything LOCALHOST
does, and more strictly: discovery only by unicast to 127.0.0.1 (initial peer, no multicast
locator), every receive locator on 127.0.0.1, UDPv4 whitelisted to 127.0.0.1, shared memory,
built-in transports off. When it is the active default profile and it verifies as
loopback-only, `prepare()` lets rmw_fastrtps take it as it is (range SYSTEM_DEFAULT, which adds
nothing) *inside this process only*; the exported environment stays LOCALHOST, so a child
process, a tool or a node without this helper still gets rmw's LOCALHOST. A missing,
unreadable or weaker profile changes nothing. Wrap `rclpy.init` in `during_init()`.
"""
from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from collections.abc import Iterator, MutableMapping
from contextlib import contextmanager
from pathlib import Path

RANGE_VAR = 'ROS_AUTOMATIC_DISCOVERY_RANGE'
PROFILE_VARS = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')
LOOPBACK = '127.0.0.1'


def _local(tag: str) -> str:
    return tag.rsplit('}', 1)[-1]


def _children(elem: ET.Element | None, name: str) -> list[ET.Element]:
    return [] if elem is None else [c for c in elem if _local(c.tag) == name]


def _text(elem: ET.Element | None) -> str:
    return '' if elem is None or elem.text is None else elem.text.strip()


def _child(elem: ET.Element | None, name: str) -> ET.Element | None:
    if elem is None:
        return None
    found = _children(elem, name)
    return found[0] if found else None


def _addresses(locator_list: ET.Element | None) -> list[str]:
    """The addresses of a Fast DDS locator list ('' for a locator without one)."""
    if locator_list is None:
        return []
    out = []
    for loc in _children(locator_list, 'locator'):
        for kind in loc:
            out.append(_text(_child(kind, 'address')))
    return out


def profile_problems(path: str | Path) -> list[str]:
    """Why the Fast DDS profile file at `path` does not keep a participant on loopback
    (empty list: it does). Checks the default participant profile: built-in transports off,
    every user transport either shared memory or UDPv4 whitelisted to 127.0.0.1 only,
    metatraffic unicast locators and initial peers on 127.0.0.1 only, no multicast locator,
    and any default unicast locator on 127.0.0.1."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        return [f'cannot read {path}: {exc}']
    profiles = root if _local(root.tag) == 'profiles' else _child(root, 'profiles')
    if profiles is None:
        return ['no <profiles> element']
    defaults = [p for p in _children(profiles, 'participant')
                if (p.get('is_default_profile') or '').lower() == 'true']
    if len(defaults) != 1:
        return [f'{len(defaults)} default participant profiles (need exactly 1)']
    rtps = _child(defaults[0], 'rtps')
    if rtps is None:
        return ['default participant profile has no <rtps>']
    problems = []
    if _text(_child(rtps, 'useBuiltinTransports')) != 'false':
        problems.append('built-in transports are not off')
    descriptors = {_text(_child(d, 'transport_id')): d for d in
                   _children(_child(profiles, 'transport_descriptors'), 'transport_descriptor')}
    ids = [_text(t) for t in _children(_child(rtps, 'userTransports'), 'transport_id')]
    if not ids:
        problems.append('no user transports')
    for tid in ids:
        d = descriptors.get(tid)
        kind = _text(_child(d, 'type'))
        if kind == 'SHM':
            continue
        if kind != 'UDPv4':
            problems.append(f'transport {tid!r} is {kind or "undefined"}, not UDPv4 or SHM')
            continue
        if [_text(a) for a in _children(_child(d, 'interfaceWhiteList'), 'address')] \
                != [LOOPBACK]:
            problems.append(f'transport {tid!r} is not whitelisted to {LOOPBACK} only')
    builtin = _child(rtps, 'builtin')
    for what, name in (('metatraffic unicast locators', 'metatrafficUnicastLocatorList'),
                       ('initial peers', 'initialPeersList')):
        addrs = _addresses(_child(builtin, name))
        if not addrs or any(a != LOOPBACK for a in addrs):
            problems.append(f'{what} are not {LOOPBACK} only')
    for parent, name in ((builtin, 'metatrafficMulticastLocatorList'),
                         (rtps, 'defaultMulticastLocatorList')):
        if _addresses(_child(parent, name)):
            problems.append(f'{name} is not empty')
    if any(a != LOOPBACK for a in _addresses(_child(rtps, 'defaultUnicastLocatorList'))):
        problems.append(f'default unicast locators are not {LOOPBACK} only')
    return problems


def prepare(environ: MutableMapping[str, str] | None = None) -> str:
    """Before rclpy.init: with discovery range LOCALHOST and a verified loopback-only default
    profile, let that profile alone configure DDS in this process (see the module doc).
    Returns what was done: 'profile' (switched), or why not ('range X', 'no profile',
    'profile rejected: ...')."""
    env = os.environ if environ is None else environ
    if env.get(RANGE_VAR, '') != 'LOCALHOST':
        return f'range {env.get(RANGE_VAR, "") or "unset"}'
    path = next((env[v] for v in PROFILE_VARS if env.get(v)), '')
    if not path:
        return 'no profile'
    problems = profile_problems(path)
    if problems:
        return 'profile rejected: ' + '; '.join(problems)
    env[RANGE_VAR] = 'SYSTEM_DEFAULT'
    return 'profile'


@contextmanager
def _range_restored(env: MutableMapping[str, str]) -> Iterator[None]:
    """The discovery range as it was once the block ends (rcl reads it inside rclpy.init,
    once), so processes this one starts get the exported value, not a switch made for one
    init."""
    before = env.get(RANGE_VAR)
    try:
        yield
    finally:
        if before is None:
            env.pop(RANGE_VAR, None)
        else:
            env[RANGE_VAR] = before


@contextmanager
def during_init(environ: MutableMapping[str, str] | None = None) -> Iterator[str]:
    """`with during_init(): rclpy.init(...)`: `prepare()` for the rclpy.init inside, then the
    environment is as before. Yields prepare()'s answer."""
    env = os.environ if environ is None else environ
    with _range_restored(env):
        yield prepare(env)


@contextmanager
def discovery_off(environ: MutableMapping[str, str] | None = None) -> Iterator[None]:
    """`with discovery_off(): rclpy.init(...)`: the context inside discovers no one (range
    OFF: rmw_fastrtps gives its participant no multicast locator and room for no remote
    participant), for a context that needs no peer; then the environment is as before."""
    env = os.environ if environ is None else environ
    with _range_restored(env):
        env[RANGE_VAR] = 'OFF'
        yield
