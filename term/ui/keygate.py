"""Who a key belongs to: the pilot's key map or the widget with the focus (issue 22: priority keys mean priority).

The pilot's keys are the app's priority bindings, one binding per key, so the app sees which key it was; before one
acts, ``pilot_key_acts`` decides, in this order:

1. Out of SAFE (the craft can fly) PANIC and SAFE (``PRIORITY_IN_FLIGHT``: 1, Esc, 0) act whatever has the focus,
   a text box included: they are never text then.
2. A text box takes every character key (letters, digits, punctuation, space), its own editing keys (←, →, Home,
   Backspace, Enter, ...) and Esc (which leaves it or closes its dialog). A screen made for typing counts as a text
   box while its box has not the focus yet (the command palette just opened, ``TYPING = True``), so a fast typist's
   letters never fall through to the gains. The pilot's other keys (F1..F12, Ctrl+L) still act.
3. A list with the focus claims its keys (``CLAIMED_KEYS``: ↑ ↓ Enter), but PANIC, SAFE and lift down.
4. Anything else: the key map.

A screen that moves the focus on a key (the parameter screen's ``/`` and Enter) does it in a priority binding of
its own, at once (``Screen.set_focus``): the keys after it are then judged with the new focus, however fast they
come.
"""

from __future__ import annotations

from collections.abc import Collection

from textual.app import App
from textual.command import CommandPalette
from textual.widgets import Input

from term.input.keymap import PRIORITY_IN_FLIGHT, SAFETY_ACTIONS, is_character_key


def pilot_key_acts(action: str, key: str, *, can_fly: bool, typing: bool, claimed: Collection[str]) -> bool:
    """Whether the pilot's ``action``, bound to ``key``, acts (else the key goes to the focused widget)."""
    if can_fly and action in PRIORITY_IN_FLIGHT:
        return True
    if typing:
        return not (is_character_key(key) or key == "escape" or key in claimed)
    return action in SAFETY_ACTIONS or key not in claimed


def focus_state(app: App[object]) -> tuple[bool, frozenset[str]]:
    """(typing, the keys the focused widget claims) for the app's screen and focus now."""
    focused = app.focused
    if isinstance(focused, Input):
        return True, frozenset(focused._bindings.key_to_bindings)  # its editing keys
    if focused is None and (isinstance(app.screen, CommandPalette) or getattr(app.screen, "TYPING", False)):
        return True, frozenset()
    return False, frozenset(getattr(focused, "CLAIMED_KEYS", ()))
