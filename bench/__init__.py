"""Alternative methods and references for the vcigen speed-vs-error benchmark."""
