"""Chief and worker of Algorithms 1 and 2, the federation schemes, aggregation, and the wire format.

* :mod:`.schemes` — one scheme per module (``paper``, ``fedavg``, ``fedavgm``/``fedadam``) behind one
  interface (``Scheme``);
* :mod:`.chief` — the chief as a pure state machine; :mod:`.chief_state` — its checkpointable state;
* :mod:`.runner` — the chief's loop over a transport; :mod:`.worker` — the worker's protocol and loop;
* :mod:`.rounds` — a round's record and the learner protocols; :mod:`.events` — the roles' events;
* :mod:`.shared_settings` — the settings every role must share, checked at join;
* :mod:`.messages` — the envelope and its validation, over :mod:`.signing` and :mod:`.rejections`;
* :mod:`.aggregation` — mean, median, trimmed and clipped means; :mod:`.topics` — topic names and ids.
"""
