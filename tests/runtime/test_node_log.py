"""A process's log file rotates by its size in bytes, whatever the text's encoding."""

from __future__ import annotations

import logging

from fleet.runtime.node_log import ProcessOutput, rotating_file


def test_log_rotates_by_bytes_of_utf8_text(tmp_path):
    line = "é" * 50  # 100 bytes in UTF-8, 50 characters
    log = rotating_file(tmp_path / "node.log", max_bytes=1000, backups=2)
    for index in range(100):
        log.emit(logging.makeLogRecord({"msg": f"{index:03d} {line}"}))
    log.close()
    files = sorted(tmp_path.iterdir())
    assert [path.name for path in files] == ["node.log", "node.log.1", "node.log.2"]
    line_bytes = len(f"000 {line}\n".encode())
    # The last line written may end past the limit by the difference of its bytes and characters.
    assert all(path.stat().st_size <= 1000 + line_bytes for path in files), [p.stat().st_size for p in files]
    assert (tmp_path / "node.log").read_text(encoding="utf-8").splitlines()[-1] == f"099 {line}"


def test_process_output_keeps_the_tail_and_writes_every_line(tmp_path):
    output = ProcessOutput(tmp_path / "logs" / "controller-1.log")
    for index in range(5):
        output.add(f"line {index} 100% done")
    output.close()
    output.add("after close: in the tail only")
    assert output.tail(2) == ["line 4 100% done", "after close: in the tail only"]
    assert output.path.read_text().splitlines() == [f"line {index} 100% done" for index in range(5)]
