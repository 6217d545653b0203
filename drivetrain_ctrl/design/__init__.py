"""Controller design (PI from specifications, robust fixed-structure tuning, H-infinity, stability
certificates): the room for the next issue; it sits above :mod:`drivetrain_ctrl.linear`."""

from __future__ import annotations
