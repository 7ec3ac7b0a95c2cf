"""The generic virtual test behind :class:`designlab.sensors.definition.SensorDefinition`."""
