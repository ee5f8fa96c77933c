"""The flight-control board's firmware as software: the main loop, modes, flight and controllers, commands,
telemetry, parameters, flash log and the radio's board side.

The floors of fcb_sim and what each may import: docs/architecture.md."""
