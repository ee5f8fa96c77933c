"""A Windows-shaped Python on Linux (tests/platform): put this folder first on PYTHONPATH of a child process.

What it changes, as Windows has it, for the project's own code (term, fcb_sim, the tests' scripts):
- fcntl, termios, tty, pty and resource cannot be imported (ModuleNotFoundError, as there);
- its ``os`` and ``signal`` lack what Windows' lack (``WINDOWS_LACKS``: os.openpty, O_NONBLOCK, set_blocking (before
  Python 3.12), setsid, uname, ...; signal.SIGHUP, SIGKILL, ...): the project's ``import os`` gets a stand-in
  without them, so an unguarded use fails here as it would there;
- sys.platform is "win32" wherever the project's code reads it.

Other packages (the standard library, pyserial, Textual, bumble, platformdirs) keep Linux's: each module outside
the project is executed with the real sys.platform and may import what Linux has, because on Windows they would
take their Windows branches (pyserial's serialwin32, Textual's Windows driver, asyncio's proactor), which cannot run
here. So this shape shows what the project's code does without the POSIX modules and with Windows' platform name;
it cannot show Windows' own kernel, its console, its sockets' select(), its paths and file locking, nor the
Windows branches of those packages.
"""

import builtins
import importlib.abc
import os
import signal
import sys
import types

REAL = sys.platform
BLOCKED = frozenset({"fcntl", "termios", "tty", "pty", "resource"})
PROJECT = ("term", "fcb_sim", "tests", "__main__")


def _ours(name: object) -> bool:
    return isinstance(name, str) and (name in PROJECT or name.startswith(tuple(p + "." for p in PROJECT)))


WINDOWS_LACKS = {
    "os": {"openpty", "forkpty", "fork", "setsid", "getsid", "setpgrp", "getpgid", "killpg", "ttyname", "uname",
           "getuid", "geteuid", "getgid", "getegid", "getgroups", "mkfifo", "mknod", "sync", "nice", "getloadavg",
           "sysconf", "statvfs", "fstatvfs", "chown", "lchown", "fchown", "pipe2", "posix_spawn", "WNOHANG",
           "O_NONBLOCK", "O_NOCTTY", "O_SYNC", "O_DSYNC", "O_CLOEXEC", "set_blocking", "get_blocking"},
    "signal": {"SIGHUP", "SIGKILL", "SIGQUIT", "SIGUSR1", "SIGUSR2", "SIGALRM", "SIGCHLD", "SIGPIPE", "SIGTSTP",
               "SIGCONT", "SIGSTOP", "SIGTTIN", "SIGTTOU", "SIGWINCH", "pause", "alarm", "setitimer", "getitimer",
               "siginterrupt", "pthread_kill", "pthread_sigmask", "sigwait"},
}


class _Without(types.ModuleType):
    """A module as the project sees it on Windows: the real one without ``lacks``."""

    def __init__(self, real: types.ModuleType, lacks: set[str]) -> None:
        super().__init__(real.__name__, real.__doc__)
        self._real, self._lacks = real, lacks

    def __getattr__(self, name: str) -> object:
        if name in self._lacks:
            raise AttributeError(f"module {self.__name__!r} has no attribute {name!r}")
        return getattr(self._real, name)

    def __dir__(self) -> list[str]:
        return [n for n in dir(self._real) if n not in self._lacks]


_SHOWN = {"os": _Without(os, WINDOWS_LACKS["os"]), "signal": _Without(signal, WINDOWS_LACKS["signal"])}
_real_import = builtins.__import__


def _import(name, globals=None, locals=None, fromlist=(), level=0):  # noqa: A002, ANN001, ANN202
    """The project's ``import fcntl`` fails as on Windows (even when another package already imported it), and
    its ``import os`` and ``import signal`` get the stand-ins."""
    if level == 0 and _ours((globals or {}).get("__name__")):
        top = name.partition(".")[0]
        if top in BLOCKED:
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        if top in _SHOWN:
            module = _real_import(name, globals, locals, fromlist, level)
            if fromlist:
                for attr in fromlist:
                    if attr in WINDOWS_LACKS[top]:
                        raise ImportError(f"cannot import name {attr!r} from {top!r}", name=top)
                return module if name != top else _SHOWN[top]
            return _SHOWN[top]
    return _real_import(name, globals, locals, fromlist, level)


builtins.__import__ = _import


class _RealPlatformWhileImporting(importlib.abc.MetaPathFinder):
    """Every module outside the project is executed with the real sys.platform (module docstring)."""

    def find_spec(self, fullname, path, target=None):  # noqa: ANN001, ANN201
        if _ours(fullname):
            return None
        for finder in sys.meta_path:
            if finder is self or not hasattr(finder, "find_spec"):
                continue
            spec = finder.find_spec(fullname, path, target)
            if spec is not None:
                loader = spec.loader
                if loader is not None and hasattr(loader, "exec_module") and not isinstance(loader, _Loader):
                    spec.loader = _Loader(loader)
                return spec
        return None


class _Loader(importlib.abc.Loader):
    def __init__(self, inner) -> None:  # noqa: ANN001
        self.inner = inner

    def create_module(self, spec):  # noqa: ANN001, ANN201
        return self.inner.create_module(spec)

    def exec_module(self, module) -> None:  # noqa: ANN001
        shown = sys.platform
        sys.platform = REAL
        try:
            self.inner.exec_module(module)
        finally:
            sys.platform = shown

    def __getattr__(self, name):  # noqa: ANN001, ANN204
        return getattr(self.inner, name)


sys.meta_path.insert(0, _RealPlatformWhileImporting())
sys.platform = "win32"
