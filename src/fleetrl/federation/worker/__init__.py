"""The worker of Algorithm 2: its state machine (:mod:`.machine`; per step: :mod:`.per_step`; without a round
barrier: :mod:`.asynchronous`) and its vocabulary (:mod:`.actions`), what it does with its learner per scheme
kind (:mod:`.play`), and the runner over a learner and a transport (:mod:`.runner`)."""
