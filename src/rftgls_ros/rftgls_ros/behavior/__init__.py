"""Walk-burrow-tug behaviour of MiniRQuad without ROS: anchor modes, the mode chooser, the
energy model, the tether bookkeeping, the state machine and the cycle report (paper section VI).

Everything here is plain Python on SI values; ``behavior_node`` only parses messages, calls
``BehaviorMachine.step`` and publishes what it returns.

    config.py    BehaviorConfig: the parameters
    signals.py   Observation (in) and Commands (out) of one step
    states.py    State, HoldCause
    machine.py   BehaviorMachine: the state table, what the phases share, the cycle tally
    walk.py, burrow.py, tug.py, retry.py, link_wait.py: the phases, each with its own state
    model.py     anchor modes, force need, energy model, mode chooser (the tether:
                 rftgls_ros.tether, shared with teleop)
    evidence.py  is an estimate usable evidence for tugging; slip.py: has the anchor slipped
    report.py, tug_series.py: the cycle report and the tug time series
"""
from .config import BehaviorConfig
from .machine import BehaviorMachine
from .model import (
                    ANCHOR_MODES,
                    AnchorMode,
                    Candidate,
                    Decision,
                    EnergyModel,
                    ForceNeed,
                    ModeChooser,
)
from .report import CycleRecord, write_report
from .signals import Commands, Observation
from .states import State

__all__ = ['ANCHOR_MODES', 'AnchorMode', 'Candidate', 'Decision', 'EnergyModel', 'ForceNeed',
           'ModeChooser', 'BehaviorConfig', 'BehaviorMachine',
           'Commands', 'Observation', 'State', 'CycleRecord', 'write_report']
