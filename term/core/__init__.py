"""Floor 1: pure and sans-IO, standard library only: the protocol package, the flash-log codec and download
reassembly, the link session, events, freshness, the schema checks and the exit codes.
"""
