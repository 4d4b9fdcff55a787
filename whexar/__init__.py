"""whexar: the asynchronous actor runtime of WHexaR, a wheeled hexapod robot.

Units: SI inside the code (metres, radians, seconds, kilograms, newtons,
amperes, volts). Files and command lines that use other units say so in the
name of every key or option (``_mm``, ``_deg``, ``_us``, ...).
"""

__version__ = "0.1.0"
