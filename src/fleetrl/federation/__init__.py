"""Chief and worker of Algorithms 1 and 2, the federation schemes, aggregation, and the wire format.

* :mod:`.schemes` — one scheme per module (``paper``, ``fedavg``, ``fedavgm``/``fedadam``, ``fedprox``,
  ``pergrad``), each a ``RoundScheme`` or a ``StepScheme``, found by name (or ``package.module:Class``);
* :mod:`.chief` — the chief as a pure state machine; :mod:`.chief_state` — the state it owns, and its data
  for checkpoints; :mod:`.chief_answer` — what it says;
* :mod:`.runner` — the chief's loop over a transport; :mod:`.worker` — the worker's protocol and loop;
* :mod:`.edge` — an edge aggregator (a site's gateway: one member of the chief standing for its members) as a
  pure state machine, over :mod:`.site_chief` (its members' chief); :mod:`.edge_runner` — its loop over two
  transports;
* :mod:`.worker_machine` — the worker as a pure state machine; :mod:`.rounds` — a round seen from the
  worker: the learner protocols, the machine's actions, a round's record; :mod:`.events` — the roles' events;
* :mod:`.shared_settings` — the settings every role must share, checked at join;
* :mod:`.messages` — the envelope and its validation, over :mod:`.signing` and :mod:`.rejections`;
* :mod:`.aggregation` — mean, median, trimmed and clipped means; :mod:`.topics` — topic names and ids.
"""
