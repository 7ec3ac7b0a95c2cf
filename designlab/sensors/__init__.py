"""The sensors: one module per sensor kind (virtual test as the paper ran it, plots, paper comparison) and SENSORS, the registry every command reads."""
