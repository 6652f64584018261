"""Views of the arena env for learning libraries: the deciders-only (semi-Markov) view, many arenas
stepped together in worker processes (`batched`), and the adapters that need a library (`rllib`,
`sb3`, and `benchmarl`'s task classes; each imports its library, which is an optional extra). The
engine and the env know nothing of them."""

from tavc_env.validation import is_number, require


def checked_reward_scale(value: object) -> float:
    """An adapter's `reward_scale` (rewards are multiplied by it; the env's `w / t`, t in ms, is
    about 0.03), or a ValueError naming it."""
    require(is_number(value) and value > 0, "reward_scale", value, "a number > 0")  # type: ignore[operator]
    return float(value)  # type: ignore[arg-type]
