"""tests/mpi: mpi_checks.py runs under mpirun (started by test_mpi.py), never in pytest."""

collect_ignore = ["mpi_checks.py"]
