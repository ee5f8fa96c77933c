"""Floor 3: what runs a link: the connection, the station (cable and radio), the model of the board the
screen shows, the phone's logic, the log download, the parameter client, the config, the simulator child, and
the quick exit of term's processes (quick_exit).
"""
