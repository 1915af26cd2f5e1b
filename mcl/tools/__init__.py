"""The tools around the filter core: what a team uses beside the robot's loop, never imported by the core.

- `mcl.tools.logs`: a robot's logs (ROS 2 MCAP, columnar .npz and CSV) read into one `RobotLog`, and written.
- `mcl.tools.formats`: poses in the formats teams speak (ROS messages, the SPL team message).
- `mcl.tools.replay`: a log replayed through a `Localizer`, as the robot would have run it.
- `mcl.tools.recording`: a run recorded to Rerun (`.rrd`).
- `mcl.tools.evaluation`: figures of merit of a run against its truth.
- `mcl.tools.tuning`: the localizer's settings searched on a team's logs (Optuna on Ray).
- `mcl.tools.ros`: the live ROS 2 node.
- `mcl.tools.testing`: hypothesis strategies, filter invariants and model contract checks for a team's tests.
- `mcl.tools.cli`: the `robocup-mcl` command.
"""
