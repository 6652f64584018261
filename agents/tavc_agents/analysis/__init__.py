"""Analysis of saved trials: statistics (`stats`), per-trial measures (`measures`), reports with
their provenance (`reports`) and figures (`plots`)."""
