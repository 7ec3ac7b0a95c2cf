"""The run of a virtual test on one design: the prediction, its record and writer, its side work,
the Monte Carlo of its uncertainty and the HTML report."""
