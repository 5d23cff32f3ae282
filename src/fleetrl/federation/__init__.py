"""Chief and worker of Algorithms 1 and 2, by role; a round is walked chief → wire → worker.

* :mod:`.schemes` — one scheme per module, found by name (or ``package.module:Class``), each of a kind (per
  round, per step, asynchronous) that brings its rules; :mod:`.aggregation` — mean, median, trimmed and
  clipped means;
* :mod:`.plan` — a run's plan as its chief and each worker see it; :mod:`.kinds` — each scheme kind's
  chief, worker machine and worker play, and what its chief keeps of the fleet;
* :mod:`.wire` — the message envelope and its validation, signing, topics;
* :mod:`.chief` — the chief as a pure state machine, its state and checkpoint, stragglers, roster, epoch;
* :mod:`.worker` — the worker as a pure state machine, what it does with its learner, and its runner;
* :mod:`.edge` — an edge aggregator: a site's chief to its units, one member to its parent;
* :mod:`.runner` — the chief's loop over a transport; :mod:`.events` — the roles' events;
  :mod:`.shared_settings` — the settings every role must share, checked at join.
"""
