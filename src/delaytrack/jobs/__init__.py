"""Jobs: a study run and its report written to a folder, what ``delaytrack simulate`` and
``delaytrack reproduce`` do. They sit above the studies (:mod:`delaytrack.experiments`), which
return results, and the reports (:mod:`delaytrack.report`), which render them.

- :mod:`delaytrack.jobs.scenario_run`: :func:`~delaytrack.jobs.scenario_run.run_to_folder`, one
  scenario run to its results folder (``delaytrack simulate``).
- :mod:`delaytrack.jobs.paper`: the paper's experiment (``delaytrack reproduce``), and
  :func:`~delaytrack.jobs.paper.reproduce`, the whole main job.
- :mod:`delaytrack.jobs.robustness`: the robustness study (``--job robustness``).
- :mod:`delaytrack.jobs.margins`: certified, exact and empirical margins (``--job margins``).
- :mod:`delaytrack.jobs.two_link`: AROLC against the outer loop on the two-link arm
  (``--job two-link``).
- :mod:`delaytrack.jobs.decision_study`: which controller and gains for which delay envelope
  (``--job decision``).

Import the jobs from their modules: each pulls in its study and the report package.
"""
