"""Federation schemes: what workers share each round, and what a worker whose criterion holds does.

* ``paper`` — the paper's scheme (Algorithms 1 and 2): each worker sends the actor's last gradient of the
  round, the chief averages the gradients, every worker applies the average through its actor optimiser; the
  first worker whose criterion holds sends its actor parameters θ, the chief forwards them to the others
  (model transfer) and that worker leaves W. The run ends when W is empty.
* ``fedavg`` — model averaging over the whole actor-critic (trunk, policy and value heads; Adam states stay
  with each worker): each worker runs its K optimisations, sends its model, the chief averages the models and
  every worker continues from the average. A worker whose criterion holds says so (a ``parameters`` message
  carrying the same model) and stays: its unit's episodes keep teaching the fleet's shared policy. The run
  ends when the criterion has held on every unit of W. docs/algorithm.md ("Federation schemes") gives the
  measurements that made it the better scheme.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

SharedPart = Literal["actor", "model"]


@dataclass(frozen=True)
class Scheme:
    """How one federation scheme works (the chief and the worker read the same description)."""

    name: str
    shares: SharedPart
    """``actor``: the actor's gradient (and θ on transfer); ``model``: the whole actor-critic's parameters"""
    round_message: str
    """the message type a still-learning worker sends each round"""
    stays_after_completion: bool
    """a worker whose criterion holds keeps learning in W (True) or transfers its θ and leaves (False)"""
    summary: str
    """one line for logs and ``--help``"""


SCHEMES: dict[str, Scheme] = {
    "paper": Scheme(
        "paper", "actor", "gradient", False,
        "average actor gradients every round; transfer θ of the first mature worker, which leaves",
    ),
    "fedavg": Scheme(
        "fedavg", "model", "model", True,
        "average whole actor-critic models every round; mature workers stay until every unit completes",
    ),
}  # fmt: skip


def get_scheme(name: str) -> Scheme:
    """The scheme called ``name``; ValueError naming the choices otherwise."""
    try:
        return SCHEMES[name]
    except KeyError:
        raise ValueError(f"unknown federation scheme {name!r} (choose {' or '.join(SCHEMES)})") from None
