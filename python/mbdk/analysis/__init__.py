"""Helpers shared by the studies: convergence measures, book-value comparison, tables, plots."""
