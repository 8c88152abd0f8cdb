"""``python -m nckemu.emulator.faces.opcua.prepare``: the umati/CNC models' address-space cache, built now
(``make nodesets`` runs it after installing the NodeSet files); ``--prefix`` prints where npm installs them."""

from nckemu.emulator.faces.opcua.nodesets import main

if __name__ == "__main__":
    raise SystemExit(main())
