"""Constants shared by the lab tests (a uniquely named module: every test folder has a
conftest.py, so `from conftest import ...` is ambiguous in one pytest session)."""

TRUTH = (4.2e5, 0.3)     # xi_n N/m^3, mu_surf of the synthetic medium
