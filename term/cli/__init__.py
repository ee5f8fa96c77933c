"""Floor 7: argument parsing and wiring; the only place that knows every part; nothing imports it.
"""
