"""Building a torch optimiser without importing ``torch._dynamo`` (1.5-2 s of imports, spent for nothing by a
process that builds an agent only to read its shapes): fleetrl never compiles, so the wrapped calls may go
straight to their functions."""

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
