"""Metric names say what the number is."""

from designlab.sensors.labels import metric_name_unit


def test_the_non_linearity_carries_its_definition():
    """One number over every channel, including channels whose span is only readout noise:
    the label says so (it read as the sensor's non-linearity: 56.87 % of span)."""
    name, unit = metric_name_unit("linearity_percent_span")
    assert unit == "% of span"
    assert "over every channel" in name and "noise-only channels included" in name
