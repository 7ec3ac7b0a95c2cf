"""Measured data: dataset cards (CSV/Parquet -> one uniform clock, units, repairs) and the seed 000 compensation models (linear, mPL, NARX)."""
