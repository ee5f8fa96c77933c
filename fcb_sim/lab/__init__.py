"""The simulator's lab bench: scenarios, the task profile, IMU replay and operation counts.

The floors of fcb_sim and what each may import: docs/architecture.md."""
