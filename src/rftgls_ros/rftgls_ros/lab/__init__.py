"""Lab pull-test tooling: bag layout, ArUco tracking, evaluation, calibration.

One idea per module; every module except `replay` is ROS-free (rosbags is pure Python), so
the lab tools run on any machine with the venv and no ROS install:

    bag_layout     topics, types, frames and metadata of one pull test; write/read (rosbags)
    bag_files      a bag as untrusted input: its files checked before rosbags opens them
    planar         SE(2) helpers of the sagittal plane (world x, z, pitch thetaB)
    render         synthetic marker images at known poses (pinhole camera, noise, blur)
    aruco_tracking video / image folder + camera calibration -> planar track of p in a bag
    predict        model predictions of one test: capacity, slip trajectory (every method)
    synthetic      sample pull-test bags made by the simulated robot (labelled synthetic)
    evaluate       measured vs. predicted peak force, dz/dx, dthetaB/|dx|: Table I, Fig. 8
    calibrate      least-squares (xi_n, mu_surf) with confidence intervals -> medium JSON
    replay         recorded bytes -> rclpy publishers (original timing, faster, lock-step)

synthetic, evaluate, calibrate and replay take `--anchor FILE.yaml` (an anchor description)
instead of the bag's robot (docs/design/six-d.md, "Lab tools").
"""
