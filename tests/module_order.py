"""The order in which ``make test`` starts the test modules (imported by tests/conftest.py)."""

# The modules that take longest on two cores, longest first (`--durations`, CPU seconds and wall). `make test`
# hands whole modules to its two test processes (`--dist loadfile`: a module's shared fixtures run once) in
# collection order, so these start first and the run ends on short modules, not on two long ones in a row.
START_FIRST = (
    "lab/tests/test_experiment_quick.py",  # fig5, table2 and peers --quick: 9 training runs, one fixture
    "runs/test_resume_roles.py",  # two chief + two worker runs side by side, kill -9 and resume
    "cli/test_continuous_run.py",
    "agent/test_agent_learner.py",  # the statistical learning test: 5 seeds up to 300 rounds
    "runs/test_train_end_to_end.py",
    "runs/test_interrupt.py",
    "cli/test_secrets.py",
    "cli/test_out_and_files.py",
    "envs/test_unit_factory_run.py",
    "cli/test_unreachable_broker.py",  # waits out connect timeouts
    "cli/test_pergrad_run.py",
    "cli/test_worker_device_link.py",  # two 2-worker runs of role processes, one through bridges
    "federation/test_federated_ppo.py",
    "runs/test_idle_cpu.py",
    "agent/test_agent_api.py",
)
