"""Optional solvers that propose plans: pure computation (no I/O), which may import a
third-party solver lazily (PyVRP, `pip install '.[solver]'`). Above the pure core, so
that both the onboard and the ground may propose."""
