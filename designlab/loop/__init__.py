"""The loop: a base model plus physical effects (one class per mechanism), fitted to measured data while they lower the held-out error."""
