"""The live loop: a controller, a delay element and a robot, running in real time over Zenoh.

The paper's experiment was a real-time programme: AROLC computed a command every ``T_c`` on a
PIONEER-3, and the input delay was injected "by halting the programme for h(t) amount of time
... between the control input computation and feeding it to the system". This package runs that
loop as three processes (nodes) that talk over Zenoh, the transport under ROS 2's
``rmw_zenoh``:

- :mod:`delaytrack.live.controller`: any controller of a scenario at ``T_c`` on absolute
  deadlines, on the latest state it received;
- :mod:`delaytrack.live.delay`: the "halting", as a network element on the command path, under
  the toolkit's rule (the robot applies the latest command with ``t_k <= t - h(t)``), with
  optional packet loss;
- :mod:`delaytrack.live.robot`: the scenario's plant stepped in real time at ``dt``.

:mod:`delaytrack.live.session` launches the three (``delaytrack live run``) and writes the
session folder; :mod:`delaytrack.live.replay` re-simulates a session offline with its realised
delays (``delaytrack live replay``). Each node logs to MCAP with ROS 2 schemas
(:mod:`delaytrack.live.log`). The optional extra ``delaytrack[live]`` installs Zenoh and the
MCAP libraries.
"""
