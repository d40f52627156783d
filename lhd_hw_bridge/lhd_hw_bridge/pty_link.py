"""A pseudo-terminal that stands in for the Due's serial port, behind a stable symlink: what
both device sides on this machine use (the emulator `fake_due.FakeDue` and the simulator in
device mode `lhd_sim_node.sim_due.SimDue`). The host side (the bridge) opens the symlink as it
would open /dev/ttyACM0."""
from __future__ import annotations

import os
import tty


def open_pty(link: str | None) -> tuple[int, int, str]:
    """(master fd, slave fd, slave path): both ends raw, the master non-blocking; `link`, if
    given, is (re)pointed at the slave atomically (a symlink renamed over the old one), so a
    host that reopens the link after an unplug finds the new device."""
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    os.set_blocking(master, False)
    path = os.ttyname(slave)
    if link:
        tmp = link + ".tmp"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(path, tmp)
        os.replace(tmp, link)
    return master, slave, path


def close_pty(master: int | None, slave: int | None) -> None:
    for fd in (master, slave):
        if fd is not None:
            try:
                os.close(fd)
            except OSError:
                pass
