"""The push comparison of docs/push.md: estimation on/off x fixed/optimal contact, two arms, Traj. 1.

Run: ``python -m studies.push_comparison`` (about a dozen 30 s closed-loop runs).
"""
from __future__ import annotations

from dataclasses import replace
from typing import Dict

from wholebody.push import PushConfig, comparison_table, describe, run_push


def study_configs(duration: float = 30.0) -> Dict[str, PushConfig]:
    """Return the comparison study of docs/push.md: estimation on/off x fixed/optimal contact, two arms, Traj. 1."""
    base = PushConfig(trajectory=2, duration=duration)
    fixed = replace(base, contact="fixed", fixed_contact_y=(-0.2,))
    two = replace(base, n_arms=2, fixed_contact_y=(-0.2, 0.2))
    t1 = replace(base, trajectory=1)
    runs = [base, replace(base, estimation=False), fixed, replace(fixed, estimation=False),
            replace(fixed, fixed_contact_y=(0.15,)), two, replace(two, estimation=False),
            replace(two, contact="fixed"), t1, replace(t1, estimation=False),
            replace(t1, contact="fixed", fixed_contact_y=(-0.25,)), replace(t1, contact="fixed", fixed_contact_y=(0.15,))]
    return {describe(c): c for c in runs}


if __name__ == "__main__":  # python -m studies.push_comparison: the table of docs/push.md
    print(comparison_table({label: run_push(cfg) for label, cfg in study_configs().items()}, markdown=True))
