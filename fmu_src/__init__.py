"""FMU sources: pure physics modules (standard library only) and the pythonfmu slaves on them."""
