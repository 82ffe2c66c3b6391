"""The lab measuring itself: speed and accuracy benchmarks."""
