"""Views of the arena env for learning libraries: the deciders-only (semi-Markov) view, and the
adapters that need a library (`rllib`, `sb3`; each imports its library, which is an optional
extra). The engine and the env know nothing of them."""
