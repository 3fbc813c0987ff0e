"""Backends: each turns a DiscreteSystem's routines into something that runs."""
