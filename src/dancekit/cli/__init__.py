"""Thin command-line interface: one module per verb, errors become one line."""
