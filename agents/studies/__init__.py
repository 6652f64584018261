"""The package's questions, one module each: the settings of a study, the trials it runs and the
report it writes. The scripts in `benchmarks/` are thin command lines over these."""
