"""A CartPole-v1 policy as a plain Python function, for ``--agent python:examples/gym_policies/cartpole.py:act``.

It pushes the cart towards where the pole leans, a little ahead of the pole's swing: it balances the default
CartPole for the whole 500 steps, and ``dsage-ray audit --domain gym`` finds the physics where it does not.
"""


def act(observation):
    """Push right (1) when the pole leans or swings right, else left (0)."""
    _, _, angle, angular_velocity = observation
    return int(angle + 0.5 * angular_velocity > 0)
