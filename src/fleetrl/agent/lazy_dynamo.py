"""Building a torch optimiser without importing ``torch._dynamo`` first.

PyTorch wraps ``Optimizer.add_param_group`` (called by every optimiser's constructor), ``zero_grad``,
``state_dict`` and ``load_state_dict`` in ``torch._disable_dynamo``, which imports ``torch._dynamo`` (and
sympy) on the first call: 1.5-2 s of imports in a fresh process (benchmarks/startup.py), spent before a
worker's first episode and, for nothing, in a process that builds an agent only to read its shapes (the
settings' check, the chief's layout). The wrapper only turns TorchDynamo off while the call runs, which
matters inside ``torch.compile`` alone; fleetrl never compiles, so the calls may go straight to the functions.
``Optimizer.step`` still imports ``torch._dynamo`` on a worker's first update (after its first episode).
"""

import sys

DEFERRED = ("add_param_group", "zero_grad", "state_dict", "load_state_dict")
"""the methods of ``torch.optim.Optimizer`` that would import ``torch._dynamo`` on their first call"""


def defer_dynamo_import() -> None:
    """Let those methods run without importing ``torch._dynamo`` (idempotent; a no-op once it is imported, or
    on a PyTorch whose methods are not wrapped this way)."""
    if "torch._dynamo" in sys.modules:
        return
    from torch.optim import Optimizer

    for name in DEFERRED:
        function = getattr(getattr(Optimizer, name), "__wrapped__", None)
        if function is not None and getattr(function, "__dynamo_disable", None) is None:
            # torch._compile._disable_dynamo caches its wrapper here; the function itself runs instead
            setattr(function, "__dynamo_disable", function)
