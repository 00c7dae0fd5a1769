"""A bounded ROS teardown for a program that is about to end: once its safe stop is done, its
nodes, context and DDS participant get `TEARDOWN_S` to go; if they are not gone by then, a
native timer writes one line to stderr and ends the process with exit code 0.

Why: with Fast DDS 2.14 (Jazzy's rmw_fastrtps), deleting a participant while one of its
discovery callbacks is in flight can spin forever (`DomainParticipantImpl::set_listener`
waits for the callback with an infinite deadline that glibc refuses as invalid, so the wait
returns at once without releasing the mutex the callback needs to finish; upstream
eProsima/Fast-DDS#6513). rmw deletes the participant in the last `rcl_node_fini` of the
process, and a launch's SIGINT stops every process at once, so the discovery callbacks of the
others' departures are most likely exactly then. The stack in the report is in
docs/design/jazzy-robot.md, "The teardown timer".

By then nothing the robot needs is left: the safe stop has run (the winch commanded to 0)
and rmw has already published the node's removal from the ROS graph before it deletes the
participant. So the program ends cleanly (0) rather than at the stop watchdog (exit 1, 8 s).

The timer is POSIX `timer_create` with SIGEV_THREAD notification, called through ctypes: its
thread is native, so it fires while the main thread spins in native code holding the GIL,
where no Python thread or signal handler could run. glibc only (Linux); elsewhere, or if the
call fails, nothing is armed and the stop watchdog stays the bound.
"""
from __future__ import annotations

import ctypes
import sys

# s after the safe stop that the ROS teardown of an exiting program may take. Measured: 3 to
# 77 ms per node (26 node stops in the SIGINT test of the four launch files, a busy loop on
# the other core), so a slow teardown is not cut; and a stopped program still ends within
# the 2 s a stop of the stack is tested to take.
TEARDOWN_S = 1.0
# s between the line on stderr and the exit: the two are separate timer threads.
_EXIT_AFTER_S = 0.05
CLOCK_MONOTONIC = 1
SIGEV_THREAD = 2


class _Sigevent(ctypes.Structure):
    """glibc's struct sigevent (64 bytes on x86-64 and aarch64) for SIGEV_THREAD."""
    _fields_ = [('sigev_value', ctypes.c_void_p),       # union sigval: the function's argument
                ('sigev_signo', ctypes.c_int),
                ('sigev_notify', ctypes.c_int),
                ('sigev_notify_function', ctypes.c_void_p),
                ('sigev_notify_attributes', ctypes.c_void_p),
                ('_pad', ctypes.c_byte * 32)]


class _Timespec(ctypes.Structure):
    _fields_ = [('tv_sec', ctypes.c_long), ('tv_nsec', ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [('it_interval', _Timespec), ('it_value', _Timespec)]


# What the timer threads read when they fire: kept alive for the life of the process.
_KEEP: list[object] = []


def _one_shot(libc, seconds: float, function, argument: int | None) -> bool:
    """A one-shot CLOCK_MONOTONIC timer that calls function(argument) in a new native thread
    `seconds` from now. False if glibc refuses."""
    event = _Sigevent(sigev_value=argument, sigev_notify=SIGEV_THREAD,
                      sigev_notify_function=ctypes.cast(function, ctypes.c_void_p).value)
    timer = ctypes.c_void_p()
    if libc.timer_create(CLOCK_MONOTONIC, ctypes.byref(event), ctypes.byref(timer)) != 0:
        return False
    whole = int(seconds)
    when = _Itimerspec(it_value=_Timespec(whole, int((seconds - whole) * 1e9)))
    _KEEP.extend((event, timer, when))
    return libc.timer_settime(timer, 0, ctypes.byref(when), None) == 0


def arm_teardown_timer(program: str, seconds: float = TEARDOWN_S) -> bool:
    """End this process with exit code 0 `seconds` from now, after one line on stderr saying
    so (module doc). Only for a process that has done its safe stop and is about to end
    (node_main.run_node arms it before the teardown, then ends the process with `finish`).
    Returns whether the timer is armed."""
    if not sys.platform.startswith('linux'):
        return False
    try:
        libc = ctypes.CDLL(None)
        perror, flush, exit_now = libc.perror, libc.fflush, libc._exit
        timer_create, timer_settime = libc.timer_create, libc.timer_settime
    except (OSError, AttributeError):
        return False
    timer_create.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p]
    timer_settime.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_void_p, ctypes.c_void_p]
    # perror appends ": " and the text of errno, 0 in a new thread: "...: Success".
    line = ctypes.create_string_buffer(
        f'{program}: the ROS teardown did not end within {seconds:g} s of the safe stop '
        f'(Fast DDS participant deletion, docs/design/jazzy-robot.md); process ended'.encode())
    _KEEP.append(line)
    for stream in (sys.stdout, sys.stderr):    # what Python has written goes out first
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    # fflush(NULL): C stdio's buffers (rcutils logs through them), which _exit would drop.
    return (_one_shot(libc, seconds, perror, ctypes.addressof(line))
            and _one_shot(libc, seconds, flush, None)
            and _one_shot(libc, seconds + _EXIT_AFTER_S, exit_now, 0))
