"""Actor-Critic PPO with a shared trunk, per the paper (Eqs. 2-7, Algorithm 2 lines 2-25)."""
