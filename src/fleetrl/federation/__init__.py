"""Chief and worker of Algorithms 1 and 2, by role; a round is walked chief → wire → worker.

* :mod:`.schemes` — one scheme per module, found by name (or ``package.module:Class``), over
  :mod:`.aggregation` (mean, median, trimmed and clipped means);
* :mod:`.plan` — each scheme kind's chief and worker machine, built for a run;
* :mod:`.wire` — the message envelope and its validation, signing, topics;
* :mod:`.chief` — the chief as a pure state machine, its state and checkpoint, stragglers, roster, epoch;
* :mod:`.worker` — the worker as a pure state machine (per round, per step, asynchronous) and its runner;
* :mod:`.edge` — an edge aggregator: a site's chief to its units, one member to its parent;
* :mod:`.runner` — the chief's loop over a transport; :mod:`.events` — the roles' events;
  :mod:`.shared_settings` — the settings every role must share, checked at join.
"""
