"""The bridge's Fast DDS profile: what it asks for, and when it says it will not get it."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ElementTree

from fleet.dataplane import receive_buffers
from fleet.dataplane.receive_buffers import PROFILES_VARIABLE, RECEIVE_BUFFER_BYTES, profile, use_large_receive_buffers

NS = "{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}"


def test_the_profile_is_the_default_participant_profile_with_the_buffer():
    root = ElementTree.fromstring(profile(123456))
    participant = root.find(f"{NS}profiles/{NS}participant")
    assert participant is not None and participant.get("is_default_profile") == "true"
    assert participant.findtext(f"{NS}rtps/{NS}listenSocketBufferSize") == "123456"


def test_it_writes_the_profile_and_names_it_for_fast_dds(tmp_path, monkeypatch):
    monkeypatch.delenv(PROFILES_VARIABLE, raising=False)
    (tmp_path / "rmem_max").write_text(f"{RECEIVE_BUFFER_BYTES}\n")
    monkeypatch.setattr(receive_buffers, "RMEM_MAX", tmp_path / "rmem_max")
    path = tmp_path / "f.bridge.fastdds.xml"
    assert use_large_receive_buffers(path) is None
    assert os.environ[PROFILES_VARIABLE] == str(path)
    assert path.read_text() == profile()


def test_it_warns_when_linux_will_grant_less(tmp_path, monkeypatch):
    monkeypatch.delenv(PROFILES_VARIABLE, raising=False)
    (tmp_path / "rmem_max").write_text("212992\n")
    monkeypatch.setattr(receive_buffers, "RMEM_MAX", tmp_path / "rmem_max")
    warning = use_large_receive_buffers(tmp_path / "p.xml")
    assert warning is not None and "net.core.rmem_max is 212992" in warning
    assert f"sysctl -w net.core.rmem_max={RECEIVE_BUFFER_BYTES}" in warning


def test_a_user_s_own_profile_is_kept(tmp_path, monkeypatch):
    monkeypatch.setenv(PROFILES_VARIABLE, "/etc/my_fastdds.xml")
    warning = use_large_receive_buffers(tmp_path / "p.xml")
    assert os.environ[PROFILES_VARIABLE] == "/etc/my_fastdds.xml"
    assert not (tmp_path / "p.xml").exists()
    assert warning is not None and "/etc/my_fastdds.xml" in warning
