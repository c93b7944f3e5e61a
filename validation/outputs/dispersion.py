"""``dispersion``: a uniform chain against the lattice's dispersion relation."""
from rk4h.validation.outputs import Output, Table


def applies(facts) -> bool:
    """A uniform chain between walls (read from the model, never its name)."""
    return facts.dense and facts.linearized and facts.model.uniform_chain() is not None


def plan(p) -> list:
    """The chain's frequencies, and one wave packet per carrier of
    ``PACKET_KP``, integrated by the registry's method under test
    (``UNDER_TEST``, RK4: :func:`rk4h.references.wavepacket.measure_group_velocity`
    and its predicted offset are RK4's), whatever the scene lists first."""
    from rk4h.references.registry import UNDER_TEST
    from rk4h.validation.plan import PACKET_KP

    return [p.spec("dispersion")] + [p.spec("packet", solver=UNDER_TEST, setting=float(kp)) for kp in PACKET_KP]


def measure(m) -> None:
    from rk4h.validation.measure import measure_dispersion

    measure_dispersion(m.scene, m.specs("dispersion"), m.specs("packet"), m.records, m.res, m.draw)


OUTPUT = Output(
    name="dispersion", rank=80, plan_rank=60, measure_rank=60,
    when="uniform chains between walls",
    what="the chain's frequencies against the lattice's dispersion relation, and RK4 wave packets: "
         "`dispersion.csv`",
    applies=applies, plan=plan, measure=measure,
    purposes={"dispersion": "the finite chain's frequencies against the dispersion relation",
              "packet": "one RK4 wave packet (the registry's UNDER_TEST) against the group velocity"},
    tables=(Table("dispersion"),),
)
