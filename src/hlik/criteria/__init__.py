"""Stage 3, the criteria: the paper's 11 human-likeness criteria and the functional ones.

- :mod:`~hlik.criteria.base`: what a criterion is (:class:`Term`, :class:`Criterion`, :class:`Sample`).
- One module per family, each criterion one class named as in the paper: :mod:`~hlik.criteria.eea`
  (EEA, EEA_r), :mod:`~hlik.criteria.soechting` (SOA_x, SOA_q), :mod:`~hlik.criteria.joints`
  (HJL, HJA_r, fJLA), :mod:`~hlik.criteria.synergy` (SYN, SYN_r, MIS), :mod:`~hlik.criteria.smoothness`
  (MJE and the solvers' smoothness), :mod:`~hlik.criteria.manipulability` (MAN_r),
  :mod:`~hlik.criteria.functional` (fPOS, fORI, fPOS_off, fORI_off).
- :mod:`~hlik.criteria.registry`: the only list of criteria; :mod:`~hlik.criteria.unified`: Eqs. 1-2;
  :mod:`~hlik.criteria.learned`: the pieces learned from a corpus (synergies, Ψ regressor, λ_R).
"""
