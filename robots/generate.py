"""Write the shipped URDF files from their generators: ``python -m robots.generate``."""

from __future__ import annotations

from robots.loading import DATA_DIR
from robots.ridgeback_iiwa import ridgeback_iiwa_urdf
from robots.shopping_cart import shopping_cart_urdf
from robots.wmra import wmra_urdf

GENERATORS = {
    "wmra.urdf": wmra_urdf,
    "ridgeback_iiwa.urdf": ridgeback_iiwa_urdf,
    "shopping_cart.urdf": shopping_cart_urdf,
}


def main() -> None:
    """Regenerate every shipped URDF in robots/."""
    for fname, gen in GENERATORS.items():
        (DATA_DIR / fname).write_text(gen())
        print(f"wrote {DATA_DIR / fname}")


if __name__ == "__main__":
    main()
