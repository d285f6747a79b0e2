"""Studies and reproductions: not library API; the library (cart, wholebody, robots) never imports them.

* `table1` (+ `table1_scene`): the cart paper's Table I (``cartpush reproduce``, ``cartpush view --scenario N``);
* `wmra_experiments` (+ `wmra_closed_form`): the WMRA paper's §IV tracking experiments and its closed forms
  (``cartpush track``);
* `placo_compare`: our whole-body QP against placo on those experiments;
* `excitation_study`: CoM convergence of the excitation-aware contact schedule;
* `push_comparison`: the closed-loop push runs of docs/push.md;
* `estimation_study`, `diagnose_study`: the estimator and the diagnosis on labelled logs;
* `testbeds/`: generators of labelled logs (`hidden_effects`, `rigid_sim`, `mujoco_cart`).
"""
