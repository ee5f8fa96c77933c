"""Floor 6: the Textual app, its screens and widgets, and the controllers the app owns.
"""
