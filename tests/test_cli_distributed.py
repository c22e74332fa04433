"""``--distributed`` never hangs: a missing process or a wrong coordinator address is one line
naming them, exit status 2, within ``--distributed-timeout``.

The processes meet on the coordinator's port before JAX's runtime starts, so these tests run
the meeting in threads of this process (JAX's runtime is never started here).
"""

import socket
import threading
import time

import pytest

from jaxkin import cli
from jaxkin.cli import distributed

WORKSPACE = ["workspace", "planar-2r", "--l1", "1", "--l2", "0.6", "--distributed"]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def environment(monkeypatch, address, count, index):
    monkeypatch.setenv("JAX_COORDINATOR_ADDRESS", address)
    monkeypatch.setenv("JAX_NUM_PROCESSES", str(count))
    monkeypatch.setenv("JAX_PROCESS_ID", str(index))


def one_line(capsys, code):
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("jaxkin: error: "), err
    assert "--distributed" in err[0]
    return err[0]


def test_missing_process_is_named_by_the_coordinator(monkeypatch, capsys):
    address = f"127.0.0.1:{free_port()}"
    environment(monkeypatch, address, 2, 0)
    start = time.monotonic()
    line = one_line(capsys, cli.main([*WORKSPACE, "--distributed-timeout", "1"]))
    assert time.monotonic() - start < 10
    assert f"process 1 did not join the coordinator at {address} within 1 s" in line


def test_coordinator_that_does_not_answer_is_named(monkeypatch, capsys):
    address = f"127.0.0.1:{free_port()}"  # nobody listens there
    environment(monkeypatch, address, 3, 2)
    line = one_line(capsys, cli.main([*WORKSPACE, "--distributed-timeout", "1"]))
    assert f"process 0 (the coordinator at {address}) did not answer process 2" in line


def test_bad_environment_is_one_line(monkeypatch, capsys):
    environment(monkeypatch, "127.0.0.1:1234", 2, 5)
    assert "JAX_PROCESS_ID=5 is not in 0..1" in one_line(capsys, cli.main(WORKSPACE))
    environment(monkeypatch, "nohost", 2, 0)
    assert "HOST:PORT" in one_line(capsys, cli.main(WORKSPACE))
    line = one_line(capsys, cli.main([*WORKSPACE, "--distributed-timeout", "0"]))
    assert "--distributed-timeout" in line


def meet(address, count, present, timeout):
    """Run the meeting for the processes ``present`` in threads; their errors (or None)."""
    errors = {}

    def run(index):
        try:
            distributed.rendezvous(address, count, index, timeout)
            errors[index] = None
        except distributed.CliError as exc:
            errors[index] = str(exc)

    threads = [threading.Thread(target=run, args=(i,)) for i in present]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout + 20)
    return errors


def test_every_process_present_meets():
    address = f"127.0.0.1:{free_port()}"
    assert meet(address, 3, [2, 1, 0], 20.0) == {0: None, 1: None, 2: None}
    with socket.create_server(("127.0.0.1", int(address.rpartition(":")[2]))):
        pass  # the port is free again for JAX's coordinator


def test_every_present_process_names_the_missing_one():
    address = f"127.0.0.1:{free_port()}"
    errors = meet(address, 3, [0, 1], 1.5)
    for index in (0, 1):
        assert f"process 2 did not join the coordinator at {address}" in errors[index]


@pytest.mark.parametrize("text", ["1.5", "60"])
def test_timeout_option_parses(text):
    from jaxkin.cli.parser import build_parser

    args = build_parser().parse_args([*WORKSPACE, "--distributed-timeout", text])
    assert args.distributed_timeout == float(text)
