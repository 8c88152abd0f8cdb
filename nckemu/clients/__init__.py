"""Clients that reproduce GET/PUT (FB2/FB3) and PI_SERV (FB4) byte for byte, on python-snap7's connection."""

from nckemu.catalogue.names import PlcVariable, Variable, parse_item, parse_variable

from .async_client import AsyncNckClient, ItemResult
from .channel840c import Channel840C, Channel840CError
from .fb import FbGet, FbOutputs, FbPiServ, FbPut
from .sync import NckClient

__all__ = ["AsyncNckClient", "Channel840C", "Channel840CError", "FbGet", "FbOutputs", "FbPiServ", "FbPut",
           "ItemResult", "NckClient", "PlcVariable", "Variable", "parse_item", "parse_variable"]
