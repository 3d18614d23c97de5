"""Diagnosis at a converged solution: which effects are missing, what is determined,
what aliases what, and whether the fit is good (seed §3.2.1, §4.3)."""
