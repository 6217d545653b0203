"""drivetrain_ctrl: model, simulate and control a dry-clutch car drivetrain."""

__version__ = "0.1.0"
