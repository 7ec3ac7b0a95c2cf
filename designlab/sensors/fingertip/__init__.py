"""The seed 001 cantilever fingertip: a printed fingertip on a steel ball over three force sensors."""
