"""The states of the walk-burrow-tug run and why a tug stopped (the diagram is in machine.py)."""
from __future__ import annotations

import enum


class State(str, enum.Enum):
    WAIT_INPUTS = 'WAIT_INPUTS'
    IDLE_MEASURE = 'IDLE_MEASURE'
    WALK = 'WALK'
    CHOOSE = 'CHOOSE'
    BURROW = 'BURROW'
    CHECK = 'CHECK'
    TUG = 'TUG'
    HOLD = 'HOLD'
    SLACKEN = 'SLACKEN'
    STEP_OFF = 'STEP_OFF'
    CYCLE_DONE = 'CYCLE_DONE'
    WAIT_LINK = 'WAIT_LINK'
    WAIT_EVIDENCE = 'WAIT_EVIDENCE'
    REFUSED = 'REFUSED'
    FINISHED = 'FINISHED'

    def __str__(self) -> str:
        return self.value


class HoldCause(enum.Enum):
    """Why the winch was stopped in a cycle (the HOLD state's cause and the cycle's outcome).
    The cycle CSV keeps its reason codes: margin_guard, capacity_short, tug_slow, slip_*
    (slip.py) and the evidence codes of an aborted attempt (evidence.py)."""

    NONE = 'none'
    GUARD = 'guard'          # margin guard: tension reached stop_ratio x capacity
    SHORT = 'short'          # capacity below the required force
    SLIP = 'slip'            # the anchor moved under load
    EVIDENCE = 'evidence'    # no usable capacity estimate (aborted attempt)
    SLOW = 'slow'            # tug timed out inside the slow band: the margin too thin to reel


# What a HOLD re-burrow is called in the transition text.
REBURROW_WHY = {HoldCause.GUARD: 'margin guard stop', HoldCause.SLIP: 'anchor slip',
                HoldCause.SHORT: 'capacity below need',
                HoldCause.SLOW: 'tug too slow inside the slow band'}

# The states in which the robot walks (the MCU runs the walk gait, the tether is paid out).
WALKING = {State.WALK, State.STEP_OFF}

ACTIVE = {State.IDLE_MEASURE, State.WALK, State.CHOOSE, State.BURROW, State.CHECK, State.TUG,
          State.HOLD, State.SLACKEN, State.STEP_OFF, State.CYCLE_DONE, State.WAIT_EVIDENCE}
TERMINAL = {State.REFUSED, State.FINISHED}
