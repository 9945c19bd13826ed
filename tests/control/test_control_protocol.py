"""Protocol validation, planning and agent-side file handling (no network, no processes)."""

from __future__ import annotations

import json

import pytest
import yaml

from fleet.errors import FleetError
from fleet.server.reconcile import plan_changes
from fleet.server.state import AgentStore, FleetState
from fleet.server.units import with_overrides
from fleet.wire import protocol as p

DIGEST = "ab" * 32


def bundle(name="robot1", digest=DIGEST, **changes) -> dict:
    data = {
        "name": name,
        "kind": "robot",
        "entry": f"{name}.launch.yaml",
        "files": {f"{name}.launch.yaml": "launch: []\n", f"{name}.params.yaml": "{}\n"},
        "options": {"isolation": "process"},
        "hot_files": [],
        "digest": digest,
    }
    data.update(changes)
    return data


def apply(**changes) -> dict:
    data = {
        "v": 1,
        "kind": "apply",
        "fleet": "two_robots",
        "agent": "hostA",
        "generation": 5,
        "domain_id": 42,
        "bundles": [bundle()],
    }
    data.update(changes)
    return data


def decode(data) -> p.ApplyRequest:
    raw = data if isinstance(data, bytes) else json.dumps(data).encode()
    return p.decode(raw, p.ApplyRequest)


def test_a_valid_apply_round_trips():
    request = decode(apply())
    assert request.bundles[0].name == "robot1"
    assert decode(p.encode(request)) == request


@pytest.mark.parametrize(
    "payload, code",
    [
        (b'{"v": 1, "kind": "apply", "fleet": "two', "malformed"),  # truncated
        (b"\xff\xfe not utf-8", "malformed"),
        (b"[]", "malformed"),
        (b"", "malformed"),
        (None, "malformed"),
        (b"[" * 100_000 + b"]" * 100_000, "malformed"),  # nested too deeply for the JSON parser
    ],
)
def test_malformed_and_truncated_messages_are_refused(payload, code):
    with pytest.raises(p.ProtocolError) as caught:
        p.decode(payload, p.ApplyRequest)
    assert caught.value.code == code


def test_oversized_message_is_refused_before_parsing():
    with pytest.raises(p.ProtocolError) as caught:
        p.decode(b" " * (p.MAX_MESSAGE_BYTES + 1), p.ApplyRequest)
    assert caught.value.code == "too_large"


def test_oversized_file_is_refused():
    big = bundle(files={"robot1.launch.yaml": "x" * (p.MAX_FILE_BYTES + 1)})
    with pytest.raises(p.ProtocolError, match="larger than"):
        decode(apply(bundles=[big]))


@pytest.mark.parametrize("version", [0, 2, "1", None])
def test_wrong_version_is_refused(version):
    with pytest.raises(p.ProtocolError) as caught:
        decode(apply(v=version))
    assert caught.value.code == "version"


@pytest.mark.parametrize(
    "name",
    ["../evil", "a/b", "/etc/passwd", ".hidden", "..", "a\\b", "x\0y", "", "a" * 200, "logs", "world.status.json"],
)
def test_file_names_escaping_the_unit_directory_are_refused(name):
    files = {"robot1.launch.yaml": "launch: []\n", name: "boom"}
    with pytest.raises(p.ProtocolError):
        decode(apply(bundles=[bundle(files=files)]))


@pytest.mark.parametrize(
    "changes",
    [
        {"fleet": "a/b"},
        {"fleet": "*"},
        {"agent": "host$"},
        {"generation": -1},
        {"generation": 2**63},  # past int64: once held, no later deploy could pass it
        {"bundles": [bundle(options={"isolation": "agent", "group_size": "abc"})]},
        {"bundles": [bundle(options={"isolation": "agent", "group_size": "0"})]},
        {"bundles": [bundle(options={"isolation": "agent", "group_size": 4})]},  # a count as text, as expanded
        {"bundles": [bundle(options={"isolation": "agent", "group_size": "٣"})]},  # a digit, not an ASCII one
        {"domain_id": 233},
        {"bundles": [bundle(), bundle()]},  # duplicate robot names
        {"bundles": [bundle(name="../x")]},
        {"bundles": [bundle(entry="missing.launch.yaml")]},
        {"bundles": [bundle(hot_files=["world.yaml"])]},
        {"bundles": [bundle(digest="not-hex")]},
        {"unexpected": 1},
        {"kind": "status"},
    ],
)
def test_invalid_fields_are_refused(changes):
    with pytest.raises(p.ProtocolError):
        decode(apply(**changes))


def test_error_replies_carry_code_and_reason():
    raw = p.error_reply(p.ProtocolError("nope", "invalid"))
    assert json.loads(raw) == {"v": 1, "kind": "error", "code": "invalid", "error": "nope"}
    with pytest.raises(p.ProtocolError, match="nope"):
        p.decode(raw, p.ApplyReply)


def test_a_generation_up_to_int64_is_valid():
    assert decode(apply(generation=2**63 - 1)).generation == 2**63 - 1


def test_a_group_size_is_a_count_of_robots():
    request = decode(apply(bundles=[bundle(options={"isolation": "agent", "group_size": "12"})]))
    assert request.bundles[0].options["group_size"] == "12"


def test_a_request_that_is_a_malformed_error_reply_is_refused_as_malformed():
    with pytest.raises(p.ProtocolError) as caught:
        p.decode(b'{"v": 1, "kind": "error"}', p.LogsRequest)
    assert caught.value.code == "malformed" and "code" in str(caught.value)


def test_a_logs_cursor_is_a_byte_offset():
    with pytest.raises(p.ProtocolError) as caught:
        p.decode(
            p.encode(p.LogsRequest(fleet="f", robot="r")).replace(b'"cursor":null', b'"cursor":{"a":-5}'), p.LogsRequest
        )
    assert caught.value.code == "invalid"


def test_a_bundle_s_digest_matches_only_its_own_files():
    from fleet.expand.bundle import Bundle

    made = Bundle(
        "robot1",
        "robot",
        "local",
        "robot1.launch.yaml",
        {"robot1.launch.yaml": "launch: []\n", "w.yaml": "a: 1\n"},
        {"isolation": "process"},
        frozenset({"w.yaml"}),
    )
    message = p.BundleMessage.from_bundle(made)
    assert message.digest_matches()
    assert message.model_copy(update={"files": {**message.files, "w.yaml": "a: 2\n"}}).digest_matches()  # hot
    changes: list[dict] = [
        {"files": {**message.files, "robot1.launch.yaml": "launch: [x]\n"}},
        {"options": {"isolation": "robot"}},
        {"hot_files": []},
    ]
    for change in changes:
        assert not message.model_copy(update=change).digest_matches(), change


def test_keys_live_under_the_fleet():
    assert p.apply_key("f", "a") == "fleet/f/agent/a/apply"
    assert p.status_query() == "fleet/*/status/**"
    assert p.status_query("f") == "fleet/f/status/**"
    assert p.fleet_of_key("fleet/f/agent/a/apply") == "f"
    assert p.fleet_of_key("fleet/*/status/**") is None


def test_param_request_needs_a_value_to_set():
    with pytest.raises(ValueError):
        p.ParamRequest(fleet="f", robot="r", node="n", name="x", op="set")
    assert p.ParamRequest(fleet="f", robot="r", node="n", name="x", op="set", value=[1.0, 2.0]).value == [1.0, 2.0]


def test_param_get_and_set_name_a_parameter_and_list_may_name_nothing():
    for op in ("get", "set"):
        with pytest.raises(ValueError, match=f"a {op} needs a node and a parameter name"):
            p.ParamRequest(fleet="f", robot="r", node="n", op=op, value=1.0)
        with pytest.raises(ValueError, match=f"a {op} needs a node and a parameter name"):
            p.ParamRequest(fleet="f", robot="r", node="", name="x", op=op, value=1.0)
    assert p.ParamRequest(fleet="f", robot="r", node="", op="list").name == ""


# -- planning ---------------------------------------------------------------------------------


def messages(*bundles_) -> dict[str, p.BundleMessage]:
    return {b["name"]: p.BundleMessage.model_validate(b) for b in bundles_}


def test_plan_changes_compares_digests():
    current = messages(bundle("r1"), bundle("r2"), bundle("r3"))
    desired = messages(bundle("r1"), bundle("r2", digest="cd" * 32), bundle("r4"))
    changes = plan_changes(current, desired)
    assert (changes.start, changes.stop, changes.restart, changes.unchanged) == (["r4"], ["r3"], ["r2"], ["r1"])
    assert plan_changes(current, current).nothing


def test_plan_changes_hot_updates_hot_files_and_retries_failed_units():
    files = {"world.launch.yaml": "launch: []\n", "world.yaml": "a: 1\n"}
    old = bundle("world", kind="world", entry="world.launch.yaml", files=files, hot_files=["world.yaml"])
    new = dict(old, files={**files, "world.yaml": "a: 2\n"})
    assert plan_changes(messages(old), messages(new)).hot_update == ["world"]
    assert plan_changes(messages(old), messages(old), again={"world"}).restart == ["world"]


# -- agent files --------------------------------------------------------------------------------


def test_a_hot_update_whose_files_cannot_be_written_fails_the_unit_and_keeps_what_it_ran(tmp_path):
    from fleet.server.units import Unit

    ran = p.BundleMessage.model_validate(bundle(hot_files=["robot1.params.yaml"]))
    new = ran.model_copy(update={"files": {**ran.files, "robot1.params.yaml": "{a: 1}\n"}})
    unit = Unit("f", ran, tmp_path / "robot1", env={})
    (tmp_path / "robot1" / "robot1.params.yaml").mkdir(parents=True)  # where the file goes: a directory
    unit.hot_update(new, {})
    assert unit.bundle is ran and unit.error.startswith("cannot write its files: "), unit.error
    assert unit.state({}).state == "failed"


def test_overrides_are_merged_into_the_params_file():
    files = {
        "robot1.launch.yaml": "launch: []\n",
        "robot1.params.yaml": yaml.safe_dump(
            {"/robot1/controller": {"ros__parameters": {"max_speed": 0.5, "loop": True}}}
        ),
    }
    merged = with_overrides(files, {"/robot1/controller": {"max_speed": 0.9}, "/robot1/battery": {"capacity": 7.0}})
    data = yaml.safe_load(merged["robot1.params.yaml"])
    assert data["/robot1/controller"]["ros__parameters"] == {"max_speed": 0.9, "loop": True}
    assert data["/robot1/battery"]["ros__parameters"] == {"capacity": 7.0}
    assert merged["robot1.launch.yaml"] == files["robot1.launch.yaml"]
    assert with_overrides(files, {}) == files


def test_an_override_of_a_nested_parameter_is_written_where_the_file_has_it():
    """`fleet param set r1 wanderer a.b 3.0` of a parameter the file nests (`a: {b: 2.5}`) used
    to add a key `a.b` beside it: one parameter written twice, which rcl settles by order."""
    section = {"a": {"b": 2.5, "c": {"d": 1}}, "x.y": 1.0, "speed": 0.2}
    files = {"r1.params.yaml": yaml.safe_dump({"/r1/wanderer": {"ros__parameters": section}})}
    overrides = {"a.b": 3.0, "a.c.d": 2, "x.y": 4.0, "a.e": True, "label": "gamma"}
    merged = with_overrides(files, {"/r1/wanderer": overrides})
    assert yaml.safe_load(merged["r1.params.yaml"])["/r1/wanderer"]["ros__parameters"] == {
        "a": {"b": 3.0, "c": {"d": 2}, "e": True},
        "x.y": 4.0,
        "speed": 0.2,
        "label": "gamma",
    }


def test_a_params_file_of_aliases_is_not_expanded_by_the_agent():
    bomb = "".join(f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10) if i else '1'}]\n" for i in range(9))
    files = {"robot1.params.yaml": bomb + "/robot1/controller: {ros__parameters: {max_speed: 0.5}}\n"}
    assert with_overrides(files, {"/robot1/controller": {"max_speed": 0.9}}) == files


def test_desired_state_is_persisted_atomically_and_restored(tmp_path):
    store = AgentStore(tmp_path / "state", "hostA")
    store.claim()
    state = FleetState(request=decode(apply()), overrides={"robot1": {"/robot1/x": {"a": 1}}})
    store.save(state)
    (store.desired_dir / "broken.json").write_text("{")
    fleets, problems = store.load()
    assert fleets == {"two_robots": state}
    assert len(problems) == 1 and "broken.json" in problems[0]
    assert not [path for path in store.desired_dir.iterdir() if path.name.startswith(".")]  # no temporaries
    with pytest.raises(FleetError, match="the state directory of agent 'hostA', not 'hostB'"):
        AgentStore(tmp_path / "state", "hostB").claim()


@pytest.mark.parametrize("name", ["hostA", "lab-pc.3", "_x", "a" * 63, "a" * 64, "-x", ".x", "a/b", "a*", "", "é"])
def test_key_name_rule_matches_the_spec_rule(name):
    from fleet.rules import key_name_problem

    assert (p.key_name_problem(name) is None) == (key_name_problem(name) is None)


def test_merged_params_file_keeps_every_value_as_rcl_reads_it():
    """Strings rcl would read bare as numbers stay strings when the agent rewrites the file."""
    from fleet.expand import yaml_emit
    from fleet.spec.yaml_source import load_yaml

    section = {"max_speed": 0.5, "tag": "1e-3", "limit": "inf", "count": "1_000", "flag": "y", "tiny": 1e-10}
    files = {"robot1.params.yaml": yaml_emit.emit({"/robot1/controller": {"ros__parameters": section}})}
    merged = with_overrides(files, {"/robot1/controller": {"max_speed": 0.9}})
    data, _ = load_yaml(merged["robot1.params.yaml"], "robot1.params.yaml", ((None, "ros__parameters"),))
    got = data["/robot1/controller"]["ros__parameters"]
    assert [(type(value), value) for value in got.values()] == [
        (type(value), value) for value in {**section, "max_speed": 0.9}.values()
    ]


def test_a_validators_own_words_come_without_pydantics_prefix():
    from pydantic import ValidationError

    with pytest.raises(ValidationError) as error:
        p.ParamRequest(fleet="f", robot="r", node="n", name="x", op="set")
    assert p.short_validation_error(error.value) == "a set needs a value"
