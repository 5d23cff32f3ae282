"""The worker of Algorithm 2: its machine for a round (:mod:`.machine`), for a step (:mod:`.per_step`) and
without a round barrier (:mod:`.asynchronous`), its phases (:mod:`.phase`), the chief it follows
(:mod:`.chief_watch`), what it asks of its runner and a round's record (:mod:`.actions`), what it does with
its learner per scheme kind (:mod:`.play`), and the runner over a learner and a transport (:mod:`.runner`)."""
