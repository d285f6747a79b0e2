"""lateral_slip offers both its forms from the registry, without importing the diagnosis (cart.effects.LateralSlip)."""

import subprocess
import sys


def test_the_registry_offers_both_lateral_slip_forms_without_the_diagnosis():
    code = (
        "import sys\n"
        "from cart.effects import registered_effects\n"
        "slip = [e for e in registered_effects() if e.name == 'lateral_slip']\n"
        "assert len(slip) == 1, slip\n"
        "assert 'cart.diagnose' not in sys.modules and 'cart.diagnose_slide' not in sys.modules\n"
        "forms = slip[0].variants()\n"
        "print(' '.join(type(f).__name__ + ':' + ','.join(f.param_names) for f in forms))\n"
        "print(' '.join(type(v).__name__ for v in forms[1].variants()))\n"
        "print('cart.diagnose' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split("\n")
    assert out[0] == "LateralSlip:compliance SlidingWheels:friction"
    assert out[1] == "SlidingWheels"  # the sliding form is its own only variant
    assert out[2] == "False"
