"""The chief of Algorithm 1: its machine (:mod:`.machine`, and :mod:`.asynchronous` for a scheme without a
round barrier), what it remembers (:mod:`.state`, :mod:`.checkpoint`), what it answers (:mod:`.answer`), who
it waits for (:mod:`.stragglers`), who may join (:mod:`.roster`), the fleet's model (:mod:`.fleet_model`), its
contributions count (:mod:`.contributions`) and its epoch (:mod:`.lease`)."""
