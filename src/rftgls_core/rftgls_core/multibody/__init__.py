"""Quasi-static multibody RFT simulation of a whole robot: a free sagittal base, legs turned
by torque-limited servos, every buried part an RFT body (docs/design/walk-burrow-physics.md).

    robot.py      the robot as a base and hinged legs (presets; description.py for URDF+YAML)
    contact.py    the buried parts of one pose and their wrenches
    roots.py      the root of RFT's set-valued closure (Newton, then a shrinking tetrahedron)
    support.py    resting parts: the resting check, their shares, the slip of a held robot
    balance.py    one instant: servo limits, rest or move
    servo.py      the XL330-M077-T datasheet and its motor line
    gaits.py      burrow, walk (Buehler clock), hold/tug
    energy.py     mechanical and electrical energy per phase
    simulate.py   settle, then step through a gait
    results.py    the trajectory, stalls, energies and status
"""
