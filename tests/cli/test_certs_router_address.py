"""`fleet certs`: what it says of the router's certificate (agents elsewhere, which dial the router by
another address, could not verify one naming only this computer) and which members it lets in."""

from __future__ import annotations

import json
import subprocess
import sys

from tests.checkout import FLEETS

NOTE = "names only this computer (127.0.0.1, localhost)"


def certs(out, *args: str) -> str:
    done = subprocess.run(
        [sys.executable, "-m", "fleet", "certs", str(FLEETS / "two_robots.yaml"), "--out", str(out), *args],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return " ".join(done.stdout.split())


def test_a_router_certificate_for_this_computer_only_is_pointed_out(tmp_path):
    assert NOTE in certs(tmp_path / "local")
    assert NOTE not in certs(tmp_path / "lan", "--router-address", "10.0.0.1")
    # A certificate kept from before is what counts, not this call's --router-address.
    assert NOTE in certs(tmp_path / "local", "--router-address", "10.0.0.1")


def test_what_it_made_is_counted_as_certificates(tmp_path):
    # Each certificate comes with its key and the configs are rewritten every time: the count is
    # of certificates, and a second run makes none.
    first = certs(tmp_path / "out")
    assert "4 new certificates with their keys (ca.pem, router.pem, local.pem, operator.pem)" in first, first
    assert "no new certificate (all kept)" in certs(tmp_path / "out")


def test_a_router_address_that_is_none_is_bad_input_and_nothing_is_made(tmp_path):
    out = tmp_path / "certs"
    spec = str(FLEETS / "two_robots.yaml")
    for address in ("bad address!", "10.0.0.300"):
        args = ["certs", spec, "-o", str(out), "--router-address", "10.0.0.1", "--router-address", address]
        done = subprocess.run([sys.executable, "-m", "fleet", *args], capture_output=True, text=True, timeout=60)
        assert done.returncode == 2 and "--router-address:" in done.stderr and address in done.stderr, done.stderr
    assert not out.exists()
    certs(out, "--router-address", "fd00::1")  # an IPv6 address is one (certs asserts it exits 0)
    assert out.is_dir()


def test_a_run_for_another_operator_keeps_the_earlier_operators_access(tmp_path):
    """The router's rules used to name only the operators of the last run: `--operator alice`
    locked out `operator`, whose certificate and config were still there."""
    out = tmp_path / "certs"
    certs(out)
    certs(out, "--operator", "alice")
    router = json.loads((out / "router.json5").read_text())
    names = {name for subject in router["access_control"]["subjects"] for name in subject.get("cert_common_names", [])}
    assert {"operator", "alice"} <= names
    assert (out / "operator-operator.json5").exists() and (out / "operator-alice.json5").exists()
