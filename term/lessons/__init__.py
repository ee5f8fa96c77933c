"""Lessons for term --sim: scripted situations with goals the simulator's truth is checked against, a score and
one line of advice, and the autopilot that flies them (and the demo). Data in ``*.toml`` here (and a teacher's,
beside them); the parts: expr (the expressions), observe (the variables), spec (the files), engine (an attempt),
autopilot, driver (all of it for a front end), progress (the pilot's file). docs/lessons.md describes the format.
"""
