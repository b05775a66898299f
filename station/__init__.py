"""Robot calibration station: camera-based relative measurement of a Thermo CRS A465 arm."""

__version__ = "0.1.0"
