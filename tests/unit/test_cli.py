from nckemu.cli import main


def test_help_exits_cleanly(capsys):
    assert main([]) == 2
    assert "nckemu" in capsys.readouterr().out
