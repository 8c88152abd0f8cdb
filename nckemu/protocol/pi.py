"""PI service (function 0x28) and PLC stop (0x29).

Job parameter: ``28`` + 7 header bytes (``00 00 00 00 00 00 FD`` as libnodave sends them) + the
parameter-block length (2 bytes) + the parameter block + the service-name length (1) + the name.
For NC services (``_N_*``) the block is a sequence of strings, each a length byte and ASCII text
with one fill byte after an even length; for PLC services it is raw (``parameter_block``).
Answer parameter: ``28`` and, when present, one function-status byte. Errors travel in the header.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from construct import Bytes, Int8ub, Int16ub, PascalString, Struct, this

from .errors import NckProtocolError, NckTruncatedError

FUNCTION_PI_SERVICE = 0x28
FUNCTION_PLC_STOP = 0x29
DEFAULT_PI_HEADER = bytes.fromhex("000000000000FD")
PLC_STOP_HEADER = bytes.fromhex("0000000000")

PI_JOB = Struct(
    "function" / Int8ub,
    "header" / Bytes(7),
    "parameter_block_length" / Int16ub,
    "parameter_block" / Bytes(this.parameter_block_length),
    "service" / PascalString(Int8ub, "ascii"),
)


@dataclass(frozen=True, slots=True)
class PiServiceSpec:
    name: str
    description: str
    argument_names: tuple[str, ...]


def _specs(*rows: tuple[str, str, str]) -> dict[str, PiServiceSpec]:
    return {name: PiServiceSpec(name, text, tuple(a for a in args.split(",") if a)) for name, text, args in rows}


# Wireshark's PI service table (names, descriptions, argument lists; the NC services' first
# argument is the address identification), plus _N_SETUDT, which Wireshark does not know.
PI_SERVICES: dict[str, PiServiceSpec] = _specs(
    ("_INSE", "Activates a PLC module", ""),
    ("_INS2", "Activates a PLC module", ""),
    ("_DELE", "Removes module from the PLC's passive file system", ""),
    ("P_PROGRAM", "PLC Start / Stop", ""),
    ("_MODU", "PLC Copy Ram to Rom", ""),
    ("_GARB", "Compress PLC memory", ""),
    ("_N_LOGIN_", "Login", "addressident,password"),
    ("_N_LOGOUT", "Logout", "addressident"),
    ("_N_CANCEL", "Cancels NC alarm", "addressident"),
    ("_N_DASAVE", "Copies data from SRAM to FLASH", "addressident"),
    ("_N_DIGIOF", "Turns off digitizing", "addressident"),
    ("_N_DIGION", "Turns on digitizing", "addressident"),
    ("_N_DZERO_", "Set all D nos. invalid for function unique D no.", "addressident"),
    ("_N_ENDEXT", "", "addressident"),
    ("_N_F_OPER", "Opens a file read-only", "addressident,filename,editwindowname"),
    ("_N_OST_OF", "Overstore OFF", "addressident"),
    ("_N_OST_ON", "Overstore ON", "addressident"),
    ("_N_SCALE_", "Unit of measurement setting (metric<->INCH)", "addressident"),
    ("_N_SETUFR", "Activates user frame", "addressident"),
    ("_N_STRTLK", "The global start disable is set", "addressident"),
    ("_N_STRTUL", "The global start disable is reset", "addressident"),
    ("_N_TMRASS", "Resets the Active status", "addressident"),
    ("_N_F_DELE", "Deletes file", "addressident,filename"),
    ("_N_EXTERN", "Selects external program for execution", "addressident,filename"),
    ("_N_EXTMOD", "Selects external program for execution", "addressident,filename"),
    ("_N_F_DELR", "Delete file even without access rights", "addressident,filename"),
    ("_N_F_XFER", "Selects file for uploading", "addressident,filename"),
    ("_N_LOCKE_", "Locks the active file for editing", "addressident,filename"),
    ("_N_SELECT", "Selects program for execution", "addressident,filename"),
    ("_N_SRTEXT", "A file is being marked in /_N_EXT_DIR", "addressident,filename"),
    ("_N_F_CLOS", "Closes file", "addressident,editwindowname"),
    ("_N_F_OPEN", "Opens file", "addressident,filename,editwindowname"),
    ("_N_F_SEEK", "Position the file search pointer",
     "addressident,editwindowname,seekpointer,windowsize,comparestring,skipcount"),
    ("_N_ASUP__", "Assigns interrupt", "addressident,interruptnr,priority,liftfast,blsync,filename"),
    ("_N_CHEKDM", "Start uniqueness check on D numbers", "addressident,magnr,dnr,spindlenumber"),
    ("_N_CHKDNO", "Check whether the tools have unique D numbers", "addressident,wznr,wznr,dnr"),
    ("_N_CONFIG", "Reconfigures machine data", "addressident,class"),
    ("_N_CRCEDN", "Creates a cutting edge by specifying an edge no.", "addressident,tnr,dnr"),
    ("_N_DELECE", "Deletes a cutting edge", "addressident,tnr,dnr"),
    ("_N_CREACE", "Creates a cutting edge", "addressident,toolnumber"),
    ("_N_CREATO", "Creates a tool", "addressident,toolnumber"),
    ("_N_DELETO", "Deletes tool", "addressident,toolnumber"),
    ("_N_CRTOCE", "Generate tool with specified edge number", "addressident,toolnumber,cenumber"),
    ("_N_DELVAR", "Delete data block",
     "addressident,datablocknumber,firstcolumnnumber,lastcolumnnumber,firstrownnumber,lastrownnumber"),
    ("_N_F_COPY", "Copies file within the NCK", "addressident,direction,sourcefilename,destinationfilename"),
    ("_N_F_DMDA", "Deletes MDA memory", "addressident,channelnumber"),
    ("_N_F_PROR", "", "addressident,filename,protection"),
    ("_N_F_PROT", "Assigns a protection level to a file", "addressident,filename,protection"),
    ("_N_F_RENA", "Renames file", "addressident,oldfilename,newfilename"),
    ("_N_FINDBL", "Activates search", "addressident,findmode"),
    ("_N_IBN_SS", "Sets the set-up switch", "addressident,switch"),
    ("_N_MMCSEM", "MMC-Semaphore", "addressident,functionnumber,semaphorevalue"),
    ("_N_NCKMOD", "The mode in which the NCK will work is being set", "addressident,onoff,mode,factor"),
    ("_N_NEWPWD", "New password", "addressident,password,passwordlevel"),
    ("_N_SEL_BL", "Selects a new block", "addressident,linenumber"),
    ("_N_SETTST", "Activate tools for replacement tool group", "addressident,magnr,weargroup,toolstatus"),
    ("_N_TMAWCO", "Set the active wear group in one magazine", "addressident,magnr,weargroup,wearsearchstrat"),
    ("_N_TMCRTC", "Create tool with specified edge number",
     "addressident,toolid,toolnumber,duplonumber,edgenumber"),
    ("_N_TMCRTO", "Creates tool in the tool management", "addressident,toolid,toolnumber,duplonumber"),
    ("_N_TMFDPL", "Searches an empty place for loading",
     "addressident,toolnumber,placenr,magnr,placerefnr,magrefnr"),
    ("_N_TMGETT", "Determines T-number for specific toolID with Duplono", "addressident,toolname,duplonumber"),
    ("_N_TMMVTL", "Loads or unloads a tool",
     "addressident,toolnumber,placenrsource,magnrsource,placenrdestination,magnrdestination"),
    ("_N_TMPCIT", "Sets increment value of the piece counter", "addressident,spindlenumber,incrementnumber"),
    # Names, texts and argument lists as tshark 4.0.17 decodes them (notes/catalogue.md 5 (d)).
    ("_N_TMFPBP", "Searches for empty location",
     "addressident,magnrfrom,placenrfrom,magnrto,placenrto,magrefnr,placerefnr,halfplacesleft,"
     "halfplacesright,halfplacesup,halfplacesdown,placetype,searchdirection"),
    ("_N_TMPOSM", "Positions a magazine or tool",
     "addressident,toolnumber,toolid,duplonumber,placenrsource,magnrsource,placenrdestination,magnrdestination"),
    ("_N_TSEARC", "Complex search via search screenforms",
     "addressident,magnrfrom,placenrfrom,magnrto,placenrto,magrefnr,placerefnr,searchdirection,kindofsearch"),
    ("_N_TRESMO", "Reset monitoring values", "addressident,toolnumber,dnr,monitoringmode"),
    # Not in Wireshark's table (tshark shows "Unknown PI Service"): SET USER DATA TAKE OVER.
    ("_N_SETUDT", "Activates current user data (tool offsets, frames)", "addressident"),
)


@dataclass(frozen=True, slots=True)
class PiServiceRequest:
    service: str
    arguments: tuple[str, ...] = ()
    header: bytes = DEFAULT_PI_HEADER
    parameter_block: bytes | None = None


@dataclass(frozen=True, slots=True)
class PiServiceResponse:
    function_status: int | None = None


@dataclass(frozen=True, slots=True)
class PlcStopRequest:
    service: str = "P_PROGRAM"
    header: bytes = PLC_STOP_HEADER


def _ascii(raw: bytes, what: str) -> str:
    try:
        return raw.decode("ascii")
    except UnicodeDecodeError:
        raise NckProtocolError(f"{what} is not ASCII") from None


def encode_arguments(arguments: tuple[str, ...]) -> bytes:
    parts = []
    for argument in arguments:
        raw = argument.encode("ascii")
        if len(raw) > 255:
            raise NckProtocolError(f"PI argument of {len(raw)} characters (max 255)")
        parts.append(bytes([len(raw)]) + raw + (b"\x00" if len(raw) % 2 == 0 else b""))
    return b"".join(parts)


def decode_arguments(block: bytes) -> tuple[str, ...]:
    arguments = []
    offset = 0
    while offset < len(block):
        length = block[offset]
        end = offset + 1 + length
        if end > len(block):
            raise NckTruncatedError(f"PI argument announces {length} characters beyond the block")
        arguments.append(_ascii(block[offset + 1:end], "PI argument"))
        offset = end + (1 if length % 2 == 0 else 0)
        if offset > len(block):
            raise NckTruncatedError("fill byte after a PI argument missing")
    return tuple(arguments)


def is_nc_service(service: str) -> bool:
    return service.startswith("_N_")


def parse_pi_request(parameter: bytes) -> PiServiceRequest:
    if len(parameter) < 11 or parameter[0] != FUNCTION_PI_SERVICE:
        raise NckTruncatedError("PI service parameter shorter than its fixed part")
    header = parameter[1:8]
    (block_length,) = struct.unpack_from(">H", parameter, 8)
    block_end = 10 + block_length
    if block_end + 1 > len(parameter):
        raise NckTruncatedError("PI parameter block runs past the parameter")
    name_length = parameter[block_end]
    if block_end + 1 + name_length != len(parameter):
        raise NckProtocolError("PI service name length does not match the parameter")
    service = _ascii(parameter[block_end + 1:], "PI service name")
    block = parameter[10:block_end]
    if is_nc_service(service):
        return PiServiceRequest(service, decode_arguments(block), header)
    return PiServiceRequest(service, (), header, block)


def build_pi_request(request: PiServiceRequest) -> bytes:
    if len(request.header) != 7:
        raise NckProtocolError("the PI header is 7 bytes")
    name = request.service.encode("ascii")
    if not 1 <= len(name) <= 255:
        raise NckProtocolError("PI service name of 1..255 characters")
    block = request.parameter_block if request.parameter_block is not None \
        else encode_arguments(request.arguments)
    return (bytes([FUNCTION_PI_SERVICE]) + request.header + struct.pack(">H", len(block)) + block
            + bytes([len(name)]) + name)


def parse_pi_response(parameter: bytes) -> PiServiceResponse:
    if not parameter or parameter[0] != FUNCTION_PI_SERVICE or len(parameter) > 2:
        raise NckProtocolError("PI answer parameter must be 28 [status]")
    return PiServiceResponse(parameter[1] if len(parameter) == 2 else None)


def build_pi_response(response: PiServiceResponse) -> bytes:
    if response.function_status is None:
        return bytes([FUNCTION_PI_SERVICE])
    return bytes([FUNCTION_PI_SERVICE, response.function_status])


def parse_plc_stop_request(parameter: bytes) -> PlcStopRequest:
    if len(parameter) < 8 or parameter[0] != FUNCTION_PLC_STOP:
        raise NckTruncatedError("PLC stop parameter shorter than its fixed part")
    name_length = parameter[6]
    if 7 + name_length != len(parameter):
        raise NckProtocolError("PLC stop service name length does not match the parameter")
    return PlcStopRequest(_ascii(parameter[7:], "PLC stop service name"), parameter[1:6])


def build_plc_stop_request(request: PlcStopRequest) -> bytes:
    name = request.service.encode("ascii")
    return bytes([FUNCTION_PLC_STOP]) + request.header + bytes([len(name)]) + name
