"""Tool addresses with one meaning, and refusals that name what this machine has (issue 44, items 1-2),
through the real CLI against a real emulator."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from nckemu.catalogue.edges import lines_unit, parameter_unit
from nckemu.cli import main
from nckemu.emulator.runner import EmulatorThread


@pytest.fixture(scope="module")
def port() -> Iterator[int]:
    with EmulatorThread() as emu:
        yield emu.port


def _get(port: int, name: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(["get", "--port", str(port), name])
    out, err = capsys.readouterr()
    return code, out, err


def test_an_edge_parameter_carries_its_own_unit(port: int, capsys) -> None:
    code, out, _ = _get(port, "cuttEdgeParam[0,T1,col1]", capsys)  # P1: the tool type, a number
    assert code == 0 and out.strip().endswith("= 120.000000")
    _, out, _ = _get(port, "cuttEdgeParam[2,T1,col1]", capsys)      # P3: length 1
    assert out.strip().endswith("= 125.000000 mm")
    for index in (25, 33):                                            # H number, number of teeth
        _, out, _ = _get(port, f"cuttEdgeParam[{index},T1,col1]", capsys)
        assert not out.strip().endswith("mm"), out
    assert parameter_unit(6) == "mm" and parameter_unit(2) == "" and lines_unit(1, 6, 35) == ""


@pytest.mark.parametrize(("name", "says"), [
    ("cuttEdgeParam[2,T1]", ["needs its tool: colN", "Tn the TO unit", "0..314", "1..315"]),
    ("/Tool/Compensation/cuttEdgeParam[u1,3]", ["needs its tool: cN"]),
    ("cuttEdgeParam[2,T1,col3]", ["no tool 3", "col1..col2 (NC)", "c1..c2 (BTSS)"]),
    ("cuttEdgeParam[2,T2,col1]", ["no TO unit 2", "names the TO unit, not the tool"]),
    ("cuttEdgeParam[40,T1,col1]", ["tool 1 has 1 cutting edge", "lines 1..35 (BTSS)", "indices 0..34 (NC)"]),
    ("r0035[V5]", ["4 drives: V1..V4 (NC) or u1..u4 (BTSS)"]),
    ("r0035[V0]", ["unit 0 outside 1..31", "V1..V31", "u1..31"]),
    ("r0035[V40]", ["unit 40 outside 1..31"]),
    ("progStatus[C3]", ["1 channel: C1 (NC) or u1 (BTSS)"]),
    ("R100", ["R0..R99", "R[u1,1..100]"]),
])
def test_a_refusal_names_the_range_on_this_machine(port: int, name: str, says: list[str], capsys) -> None:
    code, _, err = _get(port, name, capsys)
    assert code == 1
    for text in says:
        assert text in err, err


def test_pi_select_of_a_missing_program_says_no_such_program(port: int, capsys) -> None:
    code = main(["pi", "--port", str(port), "_N_SELECT", "201", "/_N_MPF_DIR/_N_NOPE_MPF"])
    err = capsys.readouterr().err
    assert code == 1 and "no such program" in err and "syntax error" not in err


def test_more_than_eight_names_go_in_several_jobs_and_v_says_so(port: int, capsys) -> None:
    names = [f"R{number}" for number in range(11)]
    assert main(["put", "--port", str(port), *[f"{name}={index}" for index, name in enumerate(names)]]) == 0
    capsys.readouterr()
    assert main(["-v", "get", "--port", str(port), *names]) == 0
    out, err = capsys.readouterr()
    assert [line.rsplit("= ", 1)[1] for line in out.splitlines()] == [f"{index}.000000" for index in range(11)]
    assert "11 names read in 2 jobs of up to 8" in err


def test_vars_searches_names_and_numbers(capsys) -> None:
    assert main(["vars", "r00"]) == 0
    out = capsys.readouterr().out
    assert "r0035" in out and "r0021" in out and "R0..R99" in out  # the drive rows, and R0 it also names
    assert main(["vars", "R"]) == 0
    assert "r0035" not in capsys.readouterr().out                   # a row's own name lists that row


def test_trace_show_words_a_header_error_for_its_service(tmp_path, capsys) -> None:
    from nckemu.clients import NckClient
    from nckemu.errors import NckError

    path = tmp_path / "pi.pcapng"
    with EmulatorThread(record_path=path) as emu, NckClient("127.0.0.1", emu.port) as client:
        with pytest.raises(NckError, match="no such program"):
            client.pi_service("_N_SELECT", "201", "/_N_MPF_DIR/_N_NOPE_MPF")
    assert main(["trace", "show", str(path)]) == 0
    out = capsys.readouterr().out
    assert "no such program or file (header error 0xD201)" in out and "syntax error" not in out


def test_an_r_parameter_past_this_machines_names_its_count(tmp_path, capsys) -> None:
    machine = tmp_path / "few_r.toml"
    machine.write_text('name = "few R"\n\n[[var]]\nname = "R"\nnumber = "R"\nmodule = 0x15\ncolumn = 1\n'
                       'areas = ["C"]\ntype = "REAL8"\nlines = 50\nwrite_level = 7\n', encoding="utf-8")
    with EmulatorThread(machine) as emu:
        code, _, err = _get(emu.port, "R60", capsys)
    assert code == 1 and "this machine has 50 lines: R0..R49 (NC) or /Channel/Parameter/R[u1,1..50] (BTSS)" in err


def test_every_pi_service_of_the_table_words_its_refusal_for_the_service(port: int) -> None:
    """Each NC PI service the controller offers, given a program, file or password that does not exist:
    a refusal is worded for a PI service (protocol/codes.py), never Wireshark's generic text."""
    from nckemu.catalogue.pi_services import NC_SERVICE_ARGUMENTS
    from nckemu.clients import NckClient
    from nckemu.errors import NckError
    from nckemu.protocol.codes import SERVICE_HEADER_ERROR_TEXTS

    worded = set(SERVICE_HEADER_ERROR_TEXTS[0x28].values())
    refused = []
    with NckClient("127.0.0.1", port) as client:
        for service, count in NC_SERVICE_ARGUMENTS.items():
            arguments = ["201", *["/_N_MPF_DIR/_N_NOPE_MPF"] * (count - 1)]
            try:
                client.pi_service(service, *arguments)
            except NckError as exc:
                text = str(exc)
                assert any(wording in text for wording in worded), (service, text)
                assert "syntax error in block name" not in text, (service, text)
                refused.append(service)
    assert {"_N_SELECT", "_N_F_DELE", "_N_LOGIN_"} <= set(refused)
