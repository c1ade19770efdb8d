"""Can the sensor see slip, and how fast: the tangential-force resolution a module layout
has at a reflex's bandwidth (``resolution``), the signature slip leaves on a held object
(``signature``), and the detector chosen from them (``detector``). Pure computation over
the physics (FEM array grid, noise model) and the gripper world's object model."""
