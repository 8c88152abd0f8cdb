"""What userdata requests, responses and pushes carry, by name: SZL records, alarm and diagnostic
messages, message service subscriptions, cyclic-data items by address, block lists, the clock. Used by
``decode``; a payload whose layout we do not know, or that does not parse, is left as it was (the
exchange keeps its service name), and never stops the decoding."""

from __future__ import annotations

from dataclasses import dataclass, field

from nckemu.errors import NckError
from nckemu.protocol import alarms, cyclic, szl, userdata
from nckemu.protocol.addresses import Address
from nckemu.protocol.s7 import DataItem

REQUEST, RESPONSE, PUSH = "request", "response", "push"
_MAX_LISTED_BLOCKS = 32


@dataclass
class Contents:
    """A payload by name: the text for ``trace show`` (``detail``) and, for cyclic services, the items
    by address with their values."""

    detail: str = ""
    items: list[tuple[Address, DataItem | None]] = field(default_factory=list)


# Cyclic subscriptions of a capture: (connection, job ID) -> the subscribed item addresses.
Subscriptions = dict[tuple[int, int], tuple[Address, ...]]


@dataclass
class UserdataState:
    """What a capture's userdata PDUs leave for later ones: cyclic subscriptions (their items name the
    values of later pushes) and SZL lists answered in several parts (named whole at the last part)."""

    subscriptions: Subscriptions = field(default_factory=dict)
    szl_parts: dict[int, list[bytes]] = field(default_factory=dict)  # connection -> the bodies so far


def userdata_contents(header: userdata.UserdataParameter, data: bytes, stage: str, connection: int,
                      state: UserdataState, request: userdata.UserdataParameter | None = None,
                      request_data: bytes = b"") -> Contents | None:
    """The contents of one userdata PDU's data part (``stage``: request, response or push; a response
    comes with its request's parameter and data). None where there is nothing to name."""
    if len(data) < 4 or data[0] not in (0xFF, 0x00):
        return None  # an error answer (0A 00 00 00) or no data: the header says it all
    body = data[4:4 + int.from_bytes(data[2:4], "big")]
    try:
        return _contents(header, data, body, stage, connection, state, request, request_data)
    except (NckError, ValueError, IndexError) as exc:
        return Contents(f"contents not decoded ({exc})")


def _contents(header: userdata.UserdataParameter, data: bytes, body: bytes, stage: str, connection: int,
              state: UserdataState, request: userdata.UserdataParameter | None,
              request_data: bytes) -> Contents | None:
    group, subfunction = header.group, header.subfunction
    if group == userdata.GROUP_CPU:
        if subfunction == szl.SUBFUNCTION_READ_SZL and stage == RESPONSE:
            return _szl_part(header, body, connection, state, request)
        if subfunction == alarms.SUBFUNCTION_DIAGNOSTIC_MESSAGE and stage != RESPONSE:
            return Contents(alarms.describe_diagnostic_message(alarms.parse_diagnostic_message(body)))
        if subfunction == 0x02:  # message service
            return Contents(alarms.describe_message_service(body, stage != RESPONSE))
        if subfunction == alarms.SUBFUNCTION_ALARM_QUERY and stage == RESPONSE:
            return Contents(alarms.describe_alarm_query_response(alarms.parse_alarm_query_response(body)))
        if subfunction in alarms.ALARM_SUBFUNCTIONS:
            message = alarms.parse_alarm_message(body, subfunction, response=stage == RESPONSE)
            return Contents(alarms.describe_alarm_message(message))
        return None
    if group == userdata.GROUP_CYCLIC:
        return _cyclic(header, body, stage, connection, state.subscriptions, request, request_data)
    if group == userdata.GROUP_BLOCK and stage == RESPONSE:
        if subfunction == szl.SUBFUNCTION_LIST_BLOCKS:
            return Contents(szl.describe_block_counts(szl.parse_block_counts(data)))
        if subfunction == 0x02:
            entries = szl.parse_blocks_of_type(body)
            kind = szl.block_type_of_request(request_data[4:]) or "block"
            listed = ", ".join(f"{kind} {e.number}" for e in entries[:_MAX_LISTED_BLOCKS])
            more = f" and {len(entries) - _MAX_LISTED_BLOCKS} more" if len(entries) > _MAX_LISTED_BLOCKS else ""
            return Contents(f"{len(entries)} blocks: {listed}{more}" if entries else "no blocks")
    if group == userdata.GROUP_BLOCK and stage == REQUEST and subfunction == 0x02:
        kind = szl.block_type_of_request(body)
        return Contents(f"type {kind}") if kind else None
    if group == userdata.GROUP_TIME and ((stage == RESPONSE and subfunction in (0x01, 0x03))
                                         or (stage == REQUEST and subfunction in (0x02, 0x04))):
        return Contents(szl.parse_clock(data).isoformat(sep=" ", timespec="milliseconds"))
    return None


def _szl_part(header: userdata.UserdataParameter, body: bytes, connection: int, state: UserdataState,
              request: userdata.UserdataParameter | None) -> Contents:
    """An SZL answer; of one in several parts, the first names what it holds, the middle ones their
    size, and the last the whole list (the parts of a connection's one long answer follow each other)."""
    more = bool(header.last_data_unit)
    if request is not None and szl.is_next_part_request(request):
        parts = state.szl_parts.get(connection)
        if parts is None:
            return Contents(f"{len(body)} more bytes of the SZL")
        parts.append(body)
        if more:
            return Contents(f"{len(body)} more bytes of the SZL (part {len(parts)})")
        del state.szl_parts[connection]
        whole = szl.describe_szl_list(szl.parse_szl_list(b"".join(parts)))
        return Contents(f"last of {len(parts)} parts: {whole}")
    if more:
        state.szl_parts[connection] = [body]
    else:
        state.szl_parts.pop(connection, None)
    return Contents(szl.describe_szl_list(szl.parse_szl_list(body), complete=not more))


def _cyclic(header: userdata.UserdataParameter, body: bytes, stage: str, connection: int,
            subscriptions: Subscriptions, request: userdata.UserdataParameter | None,
            request_data: bytes) -> Contents | None:
    if header.subfunction == cyclic.SUBFUNCTION_UNSUBSCRIBE and stage == REQUEST and len(body) == 2:
        return Contents(f"JobID={body[1]} (function {body[0]})")  # function, then the job to end
    if header.subfunction not in cyclic.SUBSCRIBING:
        return None
    if stage == REQUEST:
        subscription = cyclic.parse_subscription(body)
        detail = f"every {subscription.interval}"
        if header.subfunction == cyclic.SUBFUNCTION_CHANGE_DRIVEN_MODIFY:
            # a change of a running job: the request names it (its sequence number), as tshark shows
            detail = f"JobID={header.sequence}, {detail}"
        return Contents(detail, [(address, None) for address in subscription.items])
    values = cyclic.parse_cyclic_data(body)
    job_id = header.sequence
    if stage == RESPONSE and request is not None:
        subscription = cyclic.parse_subscription(request_data[4:])
        subscriptions[(connection, job_id)] = subscription.items
    addresses = subscriptions.get((connection, job_id))
    detail = f"JobID={job_id}"
    if addresses is None or len(addresses) != len(values):
        return Contents(detail + f", {len(values)} item{'s' if len(values) != 1 else ''} of a subscription "
                        "not in the capture" if addresses is None else detail)
    return Contents(detail, list(zip(addresses, values, strict=True)))
