"""Auditing a trained agent: search for the levels where it fails (or does worse than a reference agent),
save them reproducibly, compare agents.

* :func:`dsage_ray.audit.run.run_audit` — DSAGE with a failure-eliciting objective, then a collection;
* :mod:`dsage_ray.audit.collection` — the domain-generic collection format and how its seeds make every
  number reproducible;
* :mod:`dsage_ray.audit.summary` — how diverse the failures of a collection are;
* :mod:`dsage_ray.audit.report` — ``report.html`` and the comparison page;
* :func:`dsage_ray.audit.compare.compare_agents` — two agents on one collection (any auditable domain) with the
  same seeds;
* :class:`dsage_ray.audit.series.AuditSeries` — checkpoints audited in training order: a regression suite, a
  short warm-started search each (:mod:`dsage_ray.audit.series_report` writes ``series.html``).
"""
