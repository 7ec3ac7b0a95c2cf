"""The seed 000 arch strap: soft TPU with two printed conductive-TPU strain gauges."""
