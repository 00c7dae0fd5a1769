"""Plan the anchor: the cheapest burrow whose lower-bound capacity holds, with the burrowed
pose predicted by the whole-robot simulation instead of assumed (docs/design/burrow-planner.md).

    gaits.py      the burrow gaits a robot can run: a grid of retracting and final poses
    spread.py     the uncertain inputs of a prediction (medium covariance, servo torque)
    predict.py    one gait: simulated over the spread, capacity at each predicted pose
    bound.py      one gait's answer: predicted pose, energy, capacity and its lower bound
    plan.py       the Pareto front, the chosen gait, the paper's modes against the front
    burrowed.py   the burrowed pose a gait or mode is modelled to end in, with its band
    gait_map.py   the gait space precomputed (HDF5), built on all cores, queried onboard
"""
