"""The simulated world: the quadrotor's physics, its sensors and battery, the room, their constants.

The floors of fcb_sim and what each may import: docs/architecture.md."""
