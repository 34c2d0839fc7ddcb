"""Commissioning: the firmware measures the drive; the host turns it into a motor file."""
