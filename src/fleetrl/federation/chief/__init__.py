"""The chief of Algorithm 1: its machine (:mod:`.machine`; :mod:`.asynchronous` without a round barrier), who
it takes and what it answers (:mod:`.answer`), who it waits for (:mod:`.stragglers`), what it remembers
(:mod:`.state`, :mod:`.checkpoint`) and its epoch (:mod:`.lease`)."""
