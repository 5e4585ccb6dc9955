"""A Ctrl-C that lands inside a compiled kernel stays a Ctrl-C: the callback guard, which counts
every other exception and keeps the node running, must not swallow it."""

from types import SimpleNamespace

import numpy as np
import pytest

from activetrack_ros.node_base import GraphNode, _interrupt_inside

pytestmark = pytest.mark.ros


def _wrapped(inner: BaseException) -> SystemError:
    """What CPython raises when a C function (a numba dispatcher) returns while a signal
    handler's exception is pending."""
    try:
        try:
            raise inner
        except BaseException as exc:
            raise SystemError("returned a result with an exception set") from exc
    except SystemError as err:
        return err


def _guard():
    counted = []
    stub = SimpleNamespace(
        context=SimpleNamespace(ok=lambda: True),
        counters=SimpleNamespace(count=counted.append),
        log_limited=lambda *a: None,
    )
    return stub, counted


@pytest.mark.parametrize("inner", [KeyboardInterrupt(), SystemExit(143)])
def test_an_interrupt_wrapped_in_a_system_error_is_raised_as_itself(inner):
    stub, counted = _guard()

    def callback():
        raise _wrapped(inner)

    with pytest.raises(type(inner)):
        GraphNode.guarded(stub, callback)
    assert counted == []


def test_other_system_errors_are_counted_and_the_node_keeps_running():
    stub, counted = _guard()

    def on_track():
        raise _wrapped(ValueError("bad"))

    GraphNode.guarded(stub, on_track)
    assert counted == ["errors.on_track"]
    assert _interrupt_inside(np.linalg.LinAlgError("x")) is None


def test_a_ctrl_c_inside_the_message_decoder_is_no_undecodable_message(graph, monkeypatch):
    """rclpy's C decoder can hand the signal handler's KeyboardInterrupt back wrapped in a
    SystemError: it must stop the spin, not count a genuine message as undecodable."""
    from std_msgs.msg import String

    from activetrack_ros import node_base

    node = graph.add(GraphNode("decoding", context=graph.context))
    got = []
    node.subscribe(String, "decoded", got.append)
    pub = node.create_publisher(String, "decoded", 10)

    def interrupted_decoder(data, msg_type):
        raise _wrapped(KeyboardInterrupt())

    monkeypatch.setattr(node_base, "deserialize_message", interrupted_decoder)
    with pytest.raises(KeyboardInterrupt):  # published until the reader has matched
        graph.spin_until(lambda: pub.publish(String(data="genuine")), timeout=30.0)
    assert node.counters.counts.get("received.String") == 1
    assert not any(k.startswith(("rejected.", "errors.")) for k in node.counters.counts)
    assert got == []


def test_a_finalizer_of_an_object_a_signal_cut_short_prints_nothing(monkeypatch):
    """A signal inside an ``__init__`` leaves an object whose ``__del__`` misses an attribute
    (rclpy's Task without ``_exception``): once a signal came, that AttributeError is not
    printed; before any signal, and any other finalizer error, still is."""
    from activetrack_bringup import interrupts

    class HalfBuilt:
        def __del__(self):
            return self._exception

    printed = []
    quiet = interrupts._quiet_unraisable(printed.append)

    def unraisable(exc):
        return SimpleNamespace(exc_value=exc, object=HalfBuilt.__del__)

    missing = AttributeError("'HalfBuilt' object has no attribute '_exception'")
    monkeypatch.setattr(interrupts, "_code", None)
    quiet(unraisable(missing))  # no signal: a bug, printed
    monkeypatch.setattr(interrupts, "_code", 130)
    quiet(unraisable(missing))  # after Ctrl-C: the half-built object, quiet
    quiet(unraisable(KeyboardInterrupt()))  # the signal itself, quiet
    quiet(unraisable(ValueError("a real bug")))  # printed
    quiet(SimpleNamespace(exc_value=missing, object=print))  # not a finalizer: printed
    assert [u.exc_value for u in printed] == [missing, printed[1].exc_value, missing]
    assert isinstance(printed[1].exc_value, ValueError)
