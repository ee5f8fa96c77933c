"""What runs a board: the server (pseudo-terminal, instructor, BLE radio), the C board's loader and the
Cortex-M0 emulation.

The floors of fcb_sim and what each may import: docs/architecture.md."""
