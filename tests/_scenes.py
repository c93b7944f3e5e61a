"""Scene texts shared by the runner's tests (format with ``str.format``)."""

#: One mass between two walls: omega = sqrt((2 + 2) / 1) = 2 rad/s, period pi s.
ONE_MASS = """
name = "{name}"
model = "chain"
[params]
masses = [1.0]
springs = [2.0, 2.0]
walls = "both"
[initial]
x = [0.01]
v = [0.0]
[run]
t_end = {t_end}
h = {h}
tolerances = {tolerances}
solvers = {solvers}
outputs = {outputs}
{extra}
"""


def one_mass(name, *, t_end=2.0, h="[0.1, 0.05]", tolerances="[1e-6, 1e-9]", solvers='["rk4", "dop853"]',
             outputs='["state"]', extra=""):
    """:data:`ONE_MASS` filled in; list arguments are TOML text."""
    return ONE_MASS.format(name=name, t_end=t_end, h=h, tolerances=tolerances, solvers=solvers,
                           outputs=outputs, extra=extra)
