"""Virtual tests, metrics, calibration and stiffness fits, compensation models, measured data, the residual -> effect loop."""
