"""Floor 4: flight data on disk: recording, replay, export (MCAP, CSV) and plots.
"""
