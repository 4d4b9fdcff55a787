"""WHexaR kinematics: pure numpy, SI units, vectorised over legs and points."""
