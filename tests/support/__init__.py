"""The rigs the tests and the benchmarks share (bench/ may import them; nothing under term/ or fcb_sim/ does)."""
