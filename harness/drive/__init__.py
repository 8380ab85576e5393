"""The drives: DC motor, position controller, the record of a run and its metrics."""
