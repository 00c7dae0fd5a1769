"""Walk-burrow-tug behaviour of MiniRQuad without ROS: anchor modes, the mode chooser, the
energy model, the tether bookkeeping, the state machine and the cycle report (paper section VI).

Everything here is plain Python on SI values; ``behavior_node`` only parses messages, calls
``BehaviorMachine.step`` and publishes what it returns.
"""
from .machine import BehaviorConfig, BehaviorMachine, Commands, Observation, State
from .model import (
                    ANCHOR_MODES,
                    AnchorMode,
                    Candidate,
                    Decision,
                    EnergyModel,
                    ForceNeed,
                    ModeChooser,
                    TetherTracker,
)
from .report import CycleRecord, write_report

__all__ = ['ANCHOR_MODES', 'AnchorMode', 'Candidate', 'Decision', 'EnergyModel', 'ForceNeed',
           'ModeChooser', 'TetherTracker', 'BehaviorConfig', 'BehaviorMachine',
           'Commands', 'Observation', 'State', 'CycleRecord', 'write_report']
