"""A joystick made with SDL's virtual joystick API, for the tests of the real pygame path."""

from __future__ import annotations

import ctypes
import glob
import os

import pytest


class VirtualStick:
    """An SDL virtual joystick (4 axes, 2 buttons) in this process's SDL, as a USB stick would appear; with
    ``pad`` a virtual game controller (SDL_JOYSTICK_TYPE_GAMECONTROLLER: 6 axes, 15 buttons, SDL's own mapping)."""

    def __init__(self, pad: bool = False) -> None:
        import pygame

        # the wheel's bundled SDL (pygame-ce: pygame_ce.libs; classic pygame: pygame.libs)
        libs = glob.glob(os.path.join(os.path.dirname(pygame.__file__), "..", "pygame*.libs", "libSDL2-2*.so*"))
        if not libs:
            pytest.skip("pygame's bundled SDL2 not found")
        sdl = ctypes.CDLL(libs[0])
        sdl.SDL_JoystickAttachVirtual.argtypes = [ctypes.c_int] * 4
        sdl.SDL_JoystickOpen.restype = ctypes.c_void_p
        sdl.SDL_JoystickOpen.argtypes = [ctypes.c_int]
        sdl.SDL_JoystickSetVirtualAxis.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int16]
        sdl.SDL_JoystickSetVirtualButton.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_uint8]
        sdl.SDL_JoystickClose.argtypes = [ctypes.c_void_p]
        sdl.SDL_JoystickDetachVirtual.argtypes = [ctypes.c_int]
        self.sdl = sdl
        self.index = sdl.SDL_JoystickAttachVirtual(1, 6, 15, 0) if pad else sdl.SDL_JoystickAttachVirtual(0, 4, 2, 0)
        assert self.index >= 0
        self.handle = sdl.SDL_JoystickOpen(self.index)
        if not pad:
            self.set(0, 0, 0, 1.0)  # the lab's throttle lever pulled back: no lift

    def axes(self, *values: float, button: int | None = None) -> None:
        for axis, v in enumerate(values):
            self.sdl.SDL_JoystickSetVirtualAxis(self.handle, axis, max(-32768, min(32767, round(v * 32767))))
        if button is not None:
            self.sdl.SDL_JoystickSetVirtualButton(self.handle, button, 1)
        self.sdl.SDL_JoystickUpdate()

    def set(self, roll: float, pitch: float, yaw: float, throttle: float, fire: bool = False) -> None:
        for axis, v in enumerate((roll, pitch, yaw, throttle)):
            self.sdl.SDL_JoystickSetVirtualAxis(self.handle, axis, max(-32768, min(32767, round(v * 32767))))
        self.sdl.SDL_JoystickSetVirtualButton(self.handle, 0, int(fire))
        self.sdl.SDL_JoystickUpdate()

    def unplug(self) -> None:
        self.sdl.SDL_JoystickClose(ctypes.c_void_p(self.handle))
        self.sdl.SDL_JoystickDetachVirtual(self.index)
