"""The QP backends of both QPs (the whole-body step, `wholebody.motion.qp`; the wrench allocation,
`wholebody.contacts.allocation`), one module per backend as `qpsolvers` lays them out:

* `wholebody.qp.daqp`: `DaqpSolver`, daqp called directly (the step's default);
* `wholebody.qp.proxqp`: `ProxQPSolver`, proxsuite's dense ProxQP updated in place (the step's optional backend and
  the allocation's direct solver);
* `wholebody.qp.qpsolvers_backend`: `solve_qpsolvers`, any other solver through `qpsolvers.solve_qp`.
"""

from __future__ import annotations

from wholebody.qp.daqp import DaqpSolver
from wholebody.qp.proxqp import ProxQPSolver
from wholebody.qp.qpsolvers_backend import solve_qpsolvers

__all__ = ["DaqpSolver", "ProxQPSolver", "solve_qpsolvers"]
