#!/usr/bin/env python3
"""Stand-in for `ros2 param list/get/set/describe` against a node: calls its
rcl_interfaces parameter services (`<node>/list_parameters`,
`get_parameters`, `set_parameters`, `describe_parameters`) as
rmw_cyclonedds_cpp puts them on the wire (Eclipse Cyclone DDS, XCDR1; the
request header as in localize_fruit_peer.py). Prints one JSON object:

    {"names": [...], "values": {name: value}, "types": {name: type},
     "read_only": {name: bool}, "set": [{"name", "successful", "reason"}],
     "after": {name: value}}

    python3 param_peer.py /alacs_left/alacs [--set NAME:=VALUE ...] [--timeout S]

VALUE is read as ROS 2's command line reads it (true/false, an integer, a
number, else a string).
"""

import argparse
import json
import os
import random
import sys
import time
from dataclasses import dataclass

from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float64, int64, sequence, uint8, uint64

from localize_fruit_peer import ServiceClient, Timeout

NOT_SET, BOOL, INTEGER, DOUBLE, STRING, STRING_ARRAY = 0, 1, 2, 3, 4, 9


@dataclass
class ParameterValue(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterValue_"):
    type: uint8
    bool_value: bool
    integer_value: int64
    double_value: float64
    string_value: str
    byte_array_value: sequence[uint8]
    bool_array_value: sequence[bool]
    integer_array_value: sequence[int64]
    double_array_value: sequence[float64]
    string_array_value: sequence[str]


@dataclass
class Parameter(IdlStruct, typename="rcl_interfaces::msg::dds_::Parameter_"):
    name: str
    value: ParameterValue


@dataclass
class SetParametersResult(IdlStruct, typename="rcl_interfaces::msg::dds_::SetParametersResult_"):
    successful: bool
    reason: str


@dataclass
class ListParametersResult(IdlStruct, typename="rcl_interfaces::msg::dds_::ListParametersResult_"):
    names: sequence[str]
    prefixes: sequence[str]


@dataclass
class FloatingPointRange(IdlStruct, typename="rcl_interfaces::msg::dds_::FloatingPointRange_"):
    from_value: float64
    to_value: float64
    step: float64


@dataclass
class IntegerRange(IdlStruct, typename="rcl_interfaces::msg::dds_::IntegerRange_"):
    from_value: int64
    to_value: int64
    step: uint64


@dataclass
class ParameterDescriptor(IdlStruct, typename="rcl_interfaces::msg::dds_::ParameterDescriptor_"):
    name: str
    type: uint8
    description: str
    additional_constraints: str
    read_only: bool
    dynamic_typing: bool
    floating_point_range: sequence[FloatingPointRange]
    integer_range: sequence[IntegerRange]


@dataclass
class ListParameters_Request(IdlStruct, typename="rcl_interfaces::srv::dds_::ListParameters_Request_"):
    cdds_guid: uint64
    cdds_seq: int64
    prefixes: sequence[str]
    depth: uint64


@dataclass
class ListParameters_Response(IdlStruct, typename="rcl_interfaces::srv::dds_::ListParameters_Response_"):
    cdds_guid: uint64
    cdds_seq: int64
    result: ListParametersResult


@dataclass
class GetParameters_Request(IdlStruct, typename="rcl_interfaces::srv::dds_::GetParameters_Request_"):
    cdds_guid: uint64
    cdds_seq: int64
    names: sequence[str]


@dataclass
class GetParameters_Response(IdlStruct, typename="rcl_interfaces::srv::dds_::GetParameters_Response_"):
    cdds_guid: uint64
    cdds_seq: int64
    values: sequence[ParameterValue]


@dataclass
class SetParameters_Request(IdlStruct, typename="rcl_interfaces::srv::dds_::SetParameters_Request_"):
    cdds_guid: uint64
    cdds_seq: int64
    parameters: sequence[Parameter]


@dataclass
class SetParameters_Response(IdlStruct, typename="rcl_interfaces::srv::dds_::SetParameters_Response_"):
    cdds_guid: uint64
    cdds_seq: int64
    results: sequence[SetParametersResult]


@dataclass
class DescribeParameters_Request(
        IdlStruct, typename="rcl_interfaces::srv::dds_::DescribeParameters_Request_"):
    cdds_guid: uint64
    cdds_seq: int64
    names: sequence[str]


@dataclass
class DescribeParameters_Response(
        IdlStruct, typename="rcl_interfaces::srv::dds_::DescribeParameters_Response_"):
    cdds_guid: uint64
    cdds_seq: int64
    descriptors: sequence[ParameterDescriptor]


def value_of(v: ParameterValue):
    return {NOT_SET: None, BOOL: v.bool_value, INTEGER: v.integer_value,
            DOUBLE: v.double_value, STRING: v.string_value,
            STRING_ARRAY: list(v.string_array_value)}.get(v.type, f"<type {v.type}>")


def parameter_value(text: str) -> ParameterValue:
    """A command-line value as `ros2 param set` types it."""
    kind, b, i, d, s = STRING, False, 0, 0.0, text
    if text.lower() in ("true", "false"):
        kind, b = BOOL, text.lower() == "true"
    else:
        try:
            kind, i = INTEGER, int(text)
        except ValueError:
            try:
                kind, d = DOUBLE, float(text)
            except ValueError:
                pass
    return ParameterValue(kind, b, i, d, s if kind == STRING else "", [], [], [], [], [])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("node", help="the node's full name, e.g. /alacs_left/alacs")
    ap.add_argument("--set", action="append", default=[], metavar="NAME:=VALUE")
    ap.add_argument("--timeout", type=float, default=60.0)
    args = ap.parse_args(argv)
    log = lambda *a: print("[param peer]", *a, file=sys.stderr, flush=True)
    dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0") or 0))
    guid = random.getrandbits(63) | 1
    client = lambda base, req, rep: ServiceClient(dp, f"{args.node}/{base}", req, rep, guid)
    listing = client("list_parameters", ListParameters_Request, ListParameters_Response)
    getting = client("get_parameters", GetParameters_Request, GetParameters_Response)
    setting = client("set_parameters", SetParameters_Request, SetParameters_Response)
    describing = client("describe_parameters", DescribeParameters_Request,
                        DescribeParameters_Response)
    deadline = time.monotonic() + args.timeout
    try:
        while not all(c.matched() for c in (listing, getting, setting, describing)):
            if time.monotonic() > deadline:
                raise Timeout(f"the parameter services of {args.node} were not discovered")
            time.sleep(0.05)
        time.sleep(0.5)  # the server's reply writers match our readers too

        def call(c, make):
            return c.wait_reply(c.send(make), deadline)

        names = list(call(listing, lambda g, s: ListParameters_Request(g, s, [], 0)).result.names)
        values = call(getting, lambda g, s: GetParameters_Request(g, s, names)).values
        descriptors = call(describing,
                           lambda g, s: DescribeParameters_Request(g, s, names)).descriptors
        out = {"names": names,
               "values": {n: value_of(v) for n, v in zip(names, values)},
               "types": {n: v.type for n, v in zip(names, values)},
               "read_only": {d.name: d.read_only for d in descriptors},
               "set": [], "after": {}}
        if args.set:
            params = []
            for item in args.set:
                name, _, text = item.partition(":=")
                params.append(Parameter(name, parameter_value(text)))
            results = call(setting, lambda g, s: SetParameters_Request(g, s, params)).results
            out["set"] = [{"name": p.name, "successful": r.successful, "reason": r.reason}
                          for p, r in zip(params, results)]
            after = [p.name for p in params]
            again = call(getting, lambda g, s: GetParameters_Request(g, s, after)).values
            out["after"] = {n: value_of(v) for n, v in zip(after, again)}
    except Timeout as e:
        log(str(e))
        return 4
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
