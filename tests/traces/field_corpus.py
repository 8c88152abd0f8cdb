"""A capture of what real S7 devices send, written here frame by frame with our own codecs.

No public capture is copied: each frame reproduces a behaviour seen in public S7comm captures
(Wireshark's sample captures and ICS capture collections: S7-300/400 with STEP 7, HMIs, TIA Portal),
with the layout Wireshark's s7comm dissector decodes, and tshark (4.0.17) is the check that the
bytes mean what the comments say (``test_field_corpus.py``).

Connections:
1. an HMI on an S7-300: setup, reads of missing objects whose error items carry a length and no data,
   userdata of every function group (requests paired with responses), a pyS7-style SZL read sent as
   type 0, a userdata error, and the CPU's pushes (cyclic data, diagnostic and alarm messages, a mode
   transition) with PDU reference 0;
2. STEP 7 downloading and uploading a DB: the PLC sends the 0x1B/0x1C jobs and the programming device
   answers them, with PDU references that collide with the programming device's own; PLC-type PI
   services with block lists and arguments;
3. TIA Portal on an S7-1500: S7comm-plus (protocol id 0x72) only;
4. the same client reading classic S7comm afterwards (one capture mixes both protocols).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from pathlib import Path

from nckemu.capture import CaptureWriter
from nckemu.protocol import blocks, cotp, pi, s7, szl, userdata
from nckemu.protocol.addresses import S7AnyAddress


@dataclass
class Expected:
    """What the corpus holds, for the tests to compare with."""

    exchanges: int = 0            # jobs and userdata requests, each with its answer
    pushes: int = 0
    block_transfers: int = 0      # exchanges of functions 0x1A..0x1F
    plc_jobs: int = 0             # jobs sent by the PLC
    s7comm_plus_frames: dict[int, int] = field(default_factory=dict)
    client_s7comm_plus_frames: int = 0
    userdata_services: set[str] = field(default_factory=set)


def _job(ref: int, parameter: bytes, data: bytes = b"") -> bytes:
    return s7.build_pdu(s7.S7Pdu(s7.Rosctr.JOB, ref, parameter, data))


def _ack_data(ref: int, parameter: bytes, data: bytes = b"", error: int = 0) -> bytes:
    return s7.build_pdu(s7.S7Pdu(s7.Rosctr.ACK_DATA, ref, parameter, data, error >> 8, error & 0xFF))


def _userdata(ref: int, parameter: userdata.UserdataParameter, data: bytes) -> bytes:
    return s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, ref, userdata.build_userdata_parameter(parameter), data))


def _request(group: int, subfunction: int, sequence: int = 0, type_: int = userdata.TYPE_REQUEST
             ) -> userdata.UserdataParameter:
    return userdata.UserdataParameter(userdata.METHOD_REQUEST, type_, group, subfunction, sequence)


def _response(group: int, subfunction: int, sequence: int = 0, error_code: int = 0,
              type_: int = userdata.TYPE_RESPONSE) -> userdata.UserdataParameter:
    return userdata.UserdataParameter(userdata.METHOD_RESPONSE, type_, group, subfunction, sequence, True, 0, 0,
                                      error_code)


def _ud_data(payload: bytes, return_code: int = 0xFF, transport_size: int = 0x09) -> bytes:
    return struct.pack(">BBH", return_code, transport_size, len(payload)) + payload


# Userdata requests and their responses, one or more per function group (group, subfunction,
# request data, response data). Names as tshark 4.0.17 gives them.
_USERDATA_EXCHANGES = [
    (userdata.GROUP_PROGRAMMER, 0x02, _ud_data(b"", 0x0A, 0x00), _ud_data(b"", 0x0A, 0x00)),  # Variable status (VAT)
    (userdata.GROUP_CYCLIC, 0x01, _ud_data(b"\x00\x01\x12\x0a\x10\x02\x00\x02\x00\x00\x83\x00\x03\x20"),
     _ud_data(b"\x00\x01\xff\x04\x00\x10\x00\x2a")),                              # Cyclic transfer (subscribe)
    (userdata.GROUP_BLOCK, 0x01, _ud_data(b"", 0x0A, 0x00),
     _ud_data(b"\x30\x38\x00\x01\x30\x41\x00\x02", 0xFF, 0x09)),                  # List blocks
    (userdata.GROUP_BLOCK, 0x03, _ud_data(b"\x30\x41\x30\x30\x30\x30\x31\x41", 0xFF, 0x09),
     _ud_data(b"", 0x0A, 0x00)),                                                  # Get block info
    (userdata.GROUP_CPU, 0x13, _ud_data(b"\x00\x01\x12\x08\x1a\x00\x01\x34\x00\x00\x00\x04"),
     _ud_data(b"", 0x0A, 0x00)),                                                  # ALARM query
    (userdata.GROUP_SECURITY, 0x01, _ud_data(b"\x64\x6f\x76\x7a\x7f\x7a\x76\x57", 0xFF, 0x09),
     _ud_data(b"", 0x0A, 0x00)),                                                  # PLC password
    (userdata.GROUP_PBC, 0x01, _ud_data(b"\x00\x00\x00\x01\x00\x04\xde\xad\xbe\xef"),
     _ud_data(b"", 0x0A, 0x00)),                                                  # BSEND
    (userdata.GROUP_TIME, 0x01, _ud_data(b"", 0x0A, 0x00),
     _ud_data(b"\x00\x19\x26\x11\x23\x13\x14\x00\x00\x02", 0xFF, 0x09)),          # Read clock
    (userdata.GROUP_NC_PROGRAMMING, 0x01, _ud_data(b"_N_TEST_MPF"), _ud_data(b"", 0x0A, 0x00)),
]

# Pushes a CPU sends on its own (type 0, PDU reference 0): (group, subfunction, data).
_PUSHES = [
    (userdata.GROUP_CYCLIC, 0x01, _ud_data(b"\x00\x01\xff\x04\x00\x10\x00\x2b")),         # cyclic data
    (userdata.GROUP_CYCLIC, 0x01, _ud_data(b"\x00\x01\xff\x04\x00\x10\x00\x2c")),
    (userdata.GROUP_CPU, 0x03, _ud_data(bytes(20))),                                       # diagnostic message
    (userdata.GROUP_CPU, 0x12, _ud_data(bytes(12))),                                       # ALARM_S indication
    (userdata.GROUP_CPU, 0x11, _ud_data(bytes(12))),                                       # ALARM_SQ indication
    (userdata.GROUP_MODE_TRANSITION, 0x02, _ud_data(b"", 0x0A, 0x00)),                     # mode now RUN
]


def _missing_db_items(count: int) -> tuple[S7AnyAddress, ...]:
    return tuple(S7AnyAddress(0x02, 4, 100 + index, 0x84, 0, 0) for index in range(count))


def _error_items_with_length(count: int) -> bytes:
    # What an S7-300 answers to a read of missing DBs: 0A 00 00 04 per item and no data at all.
    return b"".join(b"\x0a\x00\x00\x04" for _ in range(count))


def _block_name(number: int, file_system: str = "P") -> blocks.BlockName:
    return blocks.BlockName("0A", number, file_system)


def write_field_corpus(path: Path) -> Expected:
    expected = Expected()
    writer = CaptureWriter.open(path)
    clock = [1_700_000_000.0]

    def send(connection: int, from_client: bool, pdu: bytes) -> None:
        clock[0] += 0.001
        writer.segment(connection, from_client, cotp.build_data_frame(pdu), timestamp=clock[0],
                       client=(f"192.168.0.{10 + connection}", 49000 + connection))

    def connect(connection: int, called_tsap: bytes = b"\x01\x02") -> None:
        clock[0] += 0.001
        client = (f"192.168.0.{10 + connection}", 49000 + connection)
        writer.segment(connection, True, cotp.build_frame(cotp.ConnectRequest(
            src_ref=connection, calling_tsap=b"\x01\x00", called_tsap=called_tsap, tpdu_size=1024)),
            timestamp=clock[0], client=client)
        writer.segment(connection, False, cotp.build_frame(cotp.ConnectConfirm(
            dst_ref=connection, src_ref=0x44, calling_tsap=b"\x01\x00", called_tsap=called_tsap, tpdu_size=1024)),
            timestamp=clock[0], client=client)

    def exchange(connection: int, client_job: bool, job: bytes, answer: bytes) -> None:
        send(connection, client_job, job)
        send(connection, not client_job, answer)
        expected.exchanges += 1
        if not client_job:
            expected.plc_jobs += 1

    # ---- 1: HMI on an S7-300
    connect(1)
    setup = s7.build_setup_communication(s7.SetupCommunication(1, 1, 240))
    exchange(1, True, _job(1, setup), _ack_data(1, setup))
    read = s7.build_read_var_request(s7.ReadVarRequest(_missing_db_items(5)))
    exchange(1, True, _job(2, read), _ack_data(2, b"\x04\x05", _error_items_with_length(5)))
    # A good item between two error items with a length: the good one's value follows directly.
    mixed = s7.build_read_var_request(s7.ReadVarRequest((
        S7AnyAddress(0x02, 4, 1, 0x84, 0, 0), S7AnyAddress(0x02, 2, 1, 0x84, 4, 0), S7AnyAddress(0x02, 4, 2, 0x84, 0, 0))))
    exchange(1, True, _job(3, mixed), _ack_data(3, b"\x04\x03", b"\x0a\x00\x00\x04" + b"\xff\x04\x00\x10\x12\x34"
                                                + b"\x0a\x00\x00\x20"))
    ref = 10
    for group, subfunction, request_data, response_data in _USERDATA_EXCHANGES:
        exchange(1, True, _userdata(ref, _request(group, subfunction), request_data),
                 _userdata(ref, _response(group, subfunction), response_data))
        expected.userdata_services.add(userdata.describe(group, subfunction))
        ref += 1
    # Read SZL with our codec; then pyS7's way (type 0 with the request method), then an SZL the CPU lacks.
    szl_parameter, szl_data = szl.build_szl_request(szl.SzlReadRequest(0x0011, 0x0000))
    answer_parameter, answer_data = szl.build_szl_response(szl.SzlReadRequest(0x0011, 0x0000),
                                                           b"\x00\x11\x00\x00\x00\x1c\x00\x01" + bytes(28))
    szl_job = s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, ref, szl_parameter, szl_data))
    exchange(1, True, szl_job, s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, ref, answer_parameter, answer_data)))
    ref += 1
    pys7 = bytearray(szl_parameter)
    pys7[5] = (userdata.TYPE_PUSH << 4) | userdata.GROUP_CPU
    exchange(1, True, s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, ref, bytes(pys7), szl_data)),
             s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, ref, answer_parameter, answer_data)))
    ref += 1
    # A long SZL in two parts: the CPU says more follows (last data unit 1, sequence 2); the client asks
    # for the next part with the 8-byte parameter form and 0A 00 00 00 (python-snap7 reading SZL 0x001C).
    first = userdata.UserdataParameter(userdata.METHOD_RESPONSE, userdata.TYPE_RESPONSE, userdata.GROUP_CPU, 0x01,
                                       2, True, 0xD5, 1, 0)
    exchange(1, True, szl_job[:4] + bytes([0, ref]) + szl_job[6:],
             _userdata(ref, first, answer_data[:4] + answer_data[4:20]))
    ref += 1
    follow = userdata.UserdataParameter(userdata.METHOD_RESPONSE, userdata.TYPE_REQUEST, userdata.GROUP_CPU, 0x01,
                                        2, True, 0, 0, 0)
    last = userdata.UserdataParameter(userdata.METHOD_RESPONSE, userdata.TYPE_RESPONSE, userdata.GROUP_CPU, 0x01,
                                      2, True, 0xD5, 0, 0)
    exchange(1, True, _userdata(ref, follow, _ud_data(b"", 0x0A, 0x00)), _userdata(ref, last, _ud_data(bytes(16))))
    ref += 1
    missing_parameter, missing_data = szl.build_szl_error_response(szl.SzlReadRequest(0x0F99, 0))
    exchange(1, True, _userdata(ref, _request(userdata.GROUP_CPU, 0x01), _ud_data(b"\x0f\x99\x00\x00")),
             s7.build_pdu(s7.S7Pdu(s7.Rosctr.USERDATA, ref, missing_parameter, missing_data)))
    expected.userdata_services.add("CPU functions -> Read SZL")
    ref += 1
    for group, subfunction, data in _PUSHES:
        send(1, False, _userdata(0, _response(group, subfunction, type_=userdata.TYPE_PUSH), data))
        expected.pushes += 1
        expected.userdata_services.add(userdata.describe(group, subfunction))
    # A read after the pushes still pairs (the pushes took PDU reference 0 on the CPU's side).
    exchange(1, True, _job(0, read), _ack_data(0, b"\x04\x05", _error_items_with_length(5)))

    # ---- 2: STEP 7 downloads DB 1, the PLC asks for it; then an upload and PLC PI services
    connect(2)
    exchange(2, True, _job(1, setup), _ack_data(1, setup))
    file_name = "_" + str(_block_name(1))
    request_download = blocks.BlockControl(blocks.REQUEST_DOWNLOAD, 0x00, 0x0000, 0, file_name, "1000074000014")
    exchange(2, True, _job(2, blocks.build_block_control(request_download)),
             _ack_data(2, blocks.build_block_control(blocks.BlockControl(blocks.REQUEST_DOWNLOAD))))
    # The PLC's own jobs: PDU reference 2 again, on its side.
    download = blocks.BlockControl(blocks.DOWNLOAD_BLOCK, 0x00, 0x0000, 0, file_name)
    exchange(2, False, _job(2, blocks.build_block_control(download)),
             _ack_data(2, blocks.build_block_control(blocks.BlockControl(blocks.DOWNLOAD_BLOCK, 0x00)),
                       struct.pack(">HH", 14, 0x00FB) + bytes(range(14))))
    ended = blocks.BlockControl(blocks.DOWNLOAD_ENDED, 0x00, 0x0000, 0, file_name)
    exchange(2, False, _job(3, blocks.build_block_control(ended)),
             _ack_data(3, blocks.build_block_control(blocks.BlockControl(blocks.DOWNLOAD_ENDED))))
    expected.block_transfers += 3
    inse = pi.PiServiceRequest("_INSE", header=pi.DEFAULT_PI_HEADER,
                               parameter_block=blocks.build_block_list((_block_name(1),)))
    exchange(2, True, _job(3, pi.build_pi_request(inse)), _ack_data(3, b"\x28"))
    upload_name = "_" + str(_block_name(1, "A"))
    exchange(2, True, _job(4, blocks.build_block_control(blocks.BlockControl(blocks.START_UPLOAD, 0, 0, 0,
                                                                             upload_name))),
             _ack_data(4, blocks.build_block_control(blocks.BlockControl(blocks.START_UPLOAD, 0x00, 0x0100, 7,
                                                                         "0000118"))))
    exchange(2, True, _job(5, blocks.build_block_control(blocks.BlockControl(blocks.UPLOAD, 0, 0, 7))),
             _ack_data(5, blocks.build_block_control(blocks.BlockControl(blocks.UPLOAD, 0x00)),
                       struct.pack(">HH", 6, 0x00FB) + bytes(6)))
    exchange(2, True, _job(6, blocks.build_block_control(blocks.BlockControl(blocks.END_UPLOAD, 0, 0, 7))),
             _ack_data(6, blocks.build_block_control(blocks.BlockControl(blocks.END_UPLOAD))))
    expected.block_transfers += 3
    dele = pi.PiServiceRequest("_DELE", parameter_block=blocks.build_block_list((_block_name(2), _block_name(3))))
    exchange(2, True, _job(7, pi.build_pi_request(dele)), _ack_data(7, b"\x28"))
    for number, (service, argument) in enumerate((("_GARB", b""), ("_MODU", b""), ("P_PROGRAM", b"P_PROGRAM"))):
        request = pi.PiServiceRequest(service, parameter_block=argument)
        exchange(2, True, _job(8 + number, pi.build_pi_request(request)), _ack_data(8 + number, b"\x28"))

    # ---- 3: TIA Portal and an S7-1500, S7comm-plus (only the framing is real: 72 01 <length> ... 72 01 00 00)
    connect(3, called_tsap=b"SIMATIC-ROOT-HMI")
    for index in range(3):
        body = bytes([0x31, 0x04, 0xCA, index, 0x00, 0x00])
        plus = b"\x72\x01" + struct.pack(">H", len(body)) + body + b"\x72\x01\x00\x00"
        send(3, True, plus)
        send(3, False, plus)
    expected.s7comm_plus_frames[3] = 6
    expected.client_s7comm_plus_frames = 3

    # ---- 4: the same engineering PC, classic S7comm
    connect(4)
    exchange(4, True, _job(1, setup), _ack_data(1, setup))
    exchange(4, True, _job(2, mixed), _ack_data(2, b"\x04\x03", b"\xff\x04\x00\x20\x00\x00\x00\x01"
                                                + b"\x05\x00\x00\x00" + b"\xff\x04\x00\x20\x00\x00\x00\x02"))
    writer.close()
    return expected
