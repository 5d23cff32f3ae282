"""Chief and worker of Algorithms 1 and 2, by role; a round is walked chief → wire → worker.

* :mod:`.schemes` — one scheme per module, each of a kind (per round, per step, asynchronous) that brings its
  rules; :mod:`.aggregation` — mean, median, trimmed and clipped means;
* :mod:`.plan` — a run's plan as its chief and each worker see it; :mod:`.kinds` — each kind's roles;
* :mod:`.wire` — the message envelope and its validation, signing, topics;
* :mod:`.chief`, :mod:`.worker`, :mod:`.edge` — the chief, the worker and an edge aggregator as pure state
  machines, each with its runner; :mod:`.runner` — the chief's loop over a transport;
* :mod:`.events` — the roles' events; :mod:`.shared_settings` — the settings every role must share.
"""
