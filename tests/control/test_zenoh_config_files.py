"""The files a Zenoh config names are read from the config's own directory, not from wherever a
command (or an agent, which moves to its state directory) happens to run: `fleet certs --out
certs` then works as the guide has it, and a computer's files work wherever they were copied."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from fleet.errors import FleetError
from fleet.wire.session import client_config, router_config, router_listens
from tests.checkout import FLEETS, run_fleet


def tls_setting(config, key: str) -> str:
    return json.loads(config.get_json(f"transport/link/tls/{key}"))


def test_a_relative_out_directory_works_from_any_working_directory(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert run_fleet(["certs", str(FLEETS / "two_robots.yaml"), "--out", "certs", "--router-address", "10.0.0.1"]) == 0
    written = json.loads((tmp_path / "certs" / "agent-local.json5").read_text())["transport"]["link"]["tls"]
    assert written["root_ca_certificate"] == "ca.pem" and written["connect_certificate"] == "local.pem"

    # Copied to another computer's directory of any name, used from yet another directory.
    copied = tmp_path / "robot" / "fleet-files"
    copied.mkdir(parents=True)
    for name in ("agent-local.json5", "local.pem", "local.key", "ca.pem"):
        shutil.copy(tmp_path / "certs" / name, copied / name)
    elsewhere = tmp_path / "state"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    config = client_config(["tls/10.0.0.1:7447"], Path("../robot/fleet-files/agent-local.json5"))
    assert tls_setting(config, "root_ca_certificate") == str(copied / "ca.pem")
    assert tls_setting(config, "connect_private_key") == str(copied / "local.key")
    router = router_config(["tls/10.0.0.1:7447"], tmp_path / "certs" / "router.json5")
    assert tls_setting(router, "listen_certificate") == str(tmp_path / "certs" / "router.pem")


def test_absolute_names_and_the_password_file_too(tmp_path, monkeypatch):
    (tmp_path / "users.txt").write_text("agent:secret\n")
    config_file = tmp_path / "agent.json5"
    config_file.write_text(
        '{transport: {auth: {usrpwd: {user: "agent", password: "secret", dictionary_file: "users.txt"}}}}'
    )
    monkeypatch.chdir("/")
    config = router_config(["tcp/127.0.0.1:7447"], config_file)
    assert json.loads(config.get_json("transport/auth/usrpwd/dictionary_file")) == str(tmp_path / "users.txt")

    config_file.write_text(
        json.dumps({"transport": {"auth": {"usrpwd": {"dictionary_file": str(tmp_path / "users.txt")}}}})
    )
    config = router_config(["tcp/127.0.0.1:7447"], config_file)
    assert json.loads(config.get_json("transport/auth/usrpwd/dictionary_file")) == str(tmp_path / "users.txt")


def test_a_missing_certificate_is_named_at_the_config_that_names_it(tmp_path):
    config_file = tmp_path / "agent-a.json5"
    config_file.write_text(json.dumps({"transport": {"link": {"tls": {"root_ca_certificate": "ca.pem"}}}}))
    with pytest.raises(FleetError) as error:
        client_config(["tls/10.0.0.1:7447"], config_file)
    assert error.value.line() == (
        f"fleet: error: {config_file}: {tmp_path / 'ca.pem'}: cannot read certificate: No such file or directory"
    )


def test_the_router_names_the_endpoints_it_listens_on_from_its_config_file(tmp_path):
    """Its log said `router listening on ` with nothing after it when only the file named them."""
    config_file = tmp_path / "router.json5"
    config_file.write_text('{listen: {endpoints: ["tcp/127.0.0.1:17481"]}}')
    assert router_listens(router_config([], config_file)) == ["tcp/127.0.0.1:17481"]
    config_file.write_text('{listen: {endpoints: {router: ["tcp/127.0.0.1:17482"], peer: []}}}')
    assert router_listens(router_config([], config_file)) == ["tcp/127.0.0.1:17482"]
    assert router_listens(router_config(["tcp/127.0.0.1:17483"], config_file)) == ["tcp/127.0.0.1:17483"]
