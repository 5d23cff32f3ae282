"""GAE (Eq. 2), critic loss (Eq. 3) and the clipped surrogate (Eq. 6) against hand-computed values."""

import math

import pytest
import torch

from fleetrl.agent.update import clipped_surrogate, critic_loss, gae, td_targets


def t(*values: float) -> torch.Tensor:
    return torch.tensor(values, dtype=torch.float64)


def test_td_targets_bootstrap_unless_terminated() -> None:
    # r + γ V(s') for a normal or truncated step, r alone for a terminal one
    targets = td_targets(t(1.0, 1.0, 0.0), t(10.0, 10.0, 10.0), t(0.0, 0.0, 1.0), gamma=0.9)
    assert torch.allclose(targets, t(10.0, 10.0, 0.0))


def test_gae_one_episode_hand_computed() -> None:
    gamma, lam = 0.9, 0.5
    rewards, values, next_values = t(1.0, 1.0, 1.0), t(2.0, 3.0, 4.0), t(3.0, 4.0, 5.0)
    zeros = t(0.0, 0.0, 0.0)
    adv = gae(rewards, values, next_values, zeros, zeros, gamma, lam)
    d0, d1, d2 = 1 + 0.9 * 3 - 2, 1 + 0.9 * 4 - 3, 1 + 0.9 * 5 - 4  # 1.7, 1.6, 1.5
    a2 = d2
    a1 = d1 + 0.45 * a2
    a0 = d0 + 0.45 * a1
    assert torch.allclose(adv, t(a0, a1, a2))
    assert math.isclose(a0, 1.7 + 0.45 * (1.6 + 0.45 * 1.5))


def test_gae_stops_at_episode_end_and_terminal_does_not_bootstrap() -> None:
    gamma, lam = 0.5, 1.0
    rewards, values, next_values = t(1.0, 1.0, 1.0), t(1.0, 1.0, 1.0), t(2.0, 2.0, 2.0)
    terminated = t(0.0, 1.0, 0.0)
    episode_end = t(0.0, 1.0, 0.0)
    adv = gae(rewards, values, next_values, terminated, episode_end, gamma, lam)
    # step 2 starts a new episode: δ2 = 1 + 0.5·2 − 1 = 1; step 1 terminal: δ1 = 1 − 1 = 0, no carry of Â2;
    # step 0: δ0 = 1 + 1 − 1 = 1, Â0 = 1 + 0.5·Â1 = 1
    assert torch.allclose(adv, t(1.0, 0.0, 1.0))


def test_gae_truncation_bootstraps_but_stops_the_sum() -> None:
    gamma, lam = 0.5, 1.0
    adv = gae(t(1.0, 1.0), t(1.0, 1.0), t(2.0, 2.0), t(0.0, 0.0), t(1.0, 0.0), gamma, lam)
    # step 0 truncated: δ0 = 1 + 0.5·2 − 1 = 1 (bootstrapped), and Â1 does not flow back into it
    assert torch.allclose(adv, t(1.0, 1.0))


def test_critic_loss_is_mean_absolute_td_error() -> None:
    values = t(1.0, 2.0, 3.0).requires_grad_(True)
    loss = critic_loss(values, t(2.0, 0.0, 3.5))
    assert math.isclose(loss.item(), (1.0 + 2.0 + 0.5) / 3)
    loss.backward()
    assert values.grad is not None
    assert torch.allclose(values.grad, t(-1.0, 1.0, -1.0) / 3)  # d|y - v|/dv = −sign(y − v)


def test_critic_loss_of_an_unknown_kind() -> None:
    with pytest.raises(ValueError, match="abs or huber"):
        critic_loss(t(1.0), t(1.0), "l2")


def test_clipped_surrogate_hand_computed() -> None:
    eps = 0.2
    ratios = t(1.5, 0.5, 1.1, 0.7)
    adv = t(2.0, 2.0, -1.0, -1.0)
    log_probs = torch.log(ratios)
    old = torch.zeros(4, dtype=torch.float64)
    value = clipped_surrogate(log_probs, old, adv, eps).item()
    # min(1.5·2, 1.2·2) = 2.4; min(0.5·2, 0.8·2) = 1.0; min(1.1·−1, 1.1·−1) = −1.1; min(0.7·−1, 0.8·−1) = −0.8
    assert math.isclose(value, (2.4 + 1.0 - 1.1 - 0.8) / 4, rel_tol=1e-12)


def test_clipped_surrogate_with_paper_eps_clips_only_far_ratios() -> None:
    # ε = 0.9: clip range [0.1, 1.9]
    value = clipped_surrogate(torch.log(t(2.5, 0.05)), t(0.0, 0.0), t(1.0, -1.0), 0.9).item()
    assert math.isclose(value, (1.9 - 0.1) / 2, rel_tol=1e-12)


def test_clipped_surrogate_gradient_vanishes_when_clipped() -> None:
    log_probs = torch.log(t(1.5)).requires_grad_(True)
    clipped_surrogate(log_probs, t(0.0), t(1.0), 0.2).backward()
    assert log_probs.grad is not None and log_probs.grad.item() == 0.0


def test_critic_loss_huber_hand_computed() -> None:
    # errors V^target − V = 0.5, −2, 3: ½·0.5² = 0.125 inside |e| < 1, |e| − ½ = 1.5 and 2.5 outside.
    values = torch.tensor([1.0, 0.0, 2.0], requires_grad=True)
    targets = torch.tensor([1.5, -2.0, 5.0])
    loss = critic_loss(values, targets, "huber")
    assert loss.item() == pytest.approx((0.125 + 1.5 + 2.5) / 3)
    loss.backward()
    assert values.grad is not None  # ∂/∂V: −e inside, −sign(e) outside, over the mean's 3
    assert values.grad.tolist() == pytest.approx([-0.5 / 3, 1.0 / 3, -1.0 / 3])
