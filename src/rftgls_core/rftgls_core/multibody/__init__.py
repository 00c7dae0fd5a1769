"""Walk and burrow with physics: a whole robot on sand, every buried part an RFT body, the legs
turned by torque-limited servos, the base free in the sagittal plane
(docs/design/walk-burrow-physics.md).

    robot.py      the robot as a base and hinged legs (presets); described.py (URDF + YAML)
    contact.py    the buried parts of one pose; evaluate.py their wrenches in one pass
    roots.py      the root of RFT's closure (ramped jumps, Levenberg-Marquardt); affine_root.py
                  the same compiled for the balances the simulation solves
    balance.py    one step: servo limits, the base twist that balances (inertia where it falls)
    servo.py      the XL330-M077-T datasheet and its motor line
    gaits.py      burrow, walk (Buehler clock), hold/tug; validate.py gaits a robot cannot run
    energy.py     mechanical and electrical energy per phase
    simulate.py   put down, settle, step through a gait; results.py what a run returns
"""
