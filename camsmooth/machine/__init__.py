"""The machine: its kinematic chain (product of exponentials, numpy and CasADi alike), the
error model that perturbs it, and the calibration that fits that model from measurements."""
