"""`rftgls bench`: named performance figures, measured in one run so they compare as ratios.

    registry.py  the sections in run order (the one place a new figure is added) and the run
    machine.py   what the machine is (CPU, SIMD, numba's target, load) and its measured peak
    engine.py    RFT engine: fused kernels and the numpy reference path, planar and 6D
    capacity.py  each limit-surface method from scratch; the 6D path
    live.py      warm-started `direct` over a stream of states
    maps.py      map queries and the paper grid's build
    report.py    the table of docs/performance.md
    timing.py    Figure and the timing helpers (a leaf: imports nothing from the package)

Nothing here is a pass/fail test: budgets are printed next to the figures, and
docs/performance.md says which CPU each budget is for.
"""
