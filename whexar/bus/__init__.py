"""Device links: the Dynamixel servo bus and the sensor-board serial line.

Control tables, the bus scheduler, the SDK adapter, the servo emulator, the
sensor-frame codec and the serial transport arrive with their issues.
"""
