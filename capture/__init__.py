"""capture: DJI telemetry (DUML over serial/USB/HID, raw captures), offline logs, attitude and per-photo geotags."""
