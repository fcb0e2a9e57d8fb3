"""C serialization of the node's DroneCAN messages, generated from the DSDL of the pinned
``dronecan`` package (host_tools/requirements-dronecan.lock).

The DSDL definitions are never copied into this repository: this generator reads them from the
installed ``dronecan`` package (its parser gives each type's fields, bit lengths, cast modes,
data type id and signature) and writes

* ``firmware/app/dronecan/dsdl_gen.h`` / ``dsdl_gen.c``: a C struct per type and its
  ``_encode`` / ``_decode`` functions (bit work only, on the helpers of ``dsdl_bits.h``), with the
  DroneCAN rules the Python library applies: little-endian bytes of each field in a big-endian
  bit stream, saturated casts, dynamic array length prefixes, union tags, and the tail array
  optimisation of the last field of the top-level type;
* ``tests/c/dronecan/dsdl_dump_gen.c``: a printer of every field of every type as JSON, used by
  the test that compares the C decoding with the Python library's (tests/python/test_dsdl.py).

::

    python -m attekf.dsdlgen generate     # rewrite the generated files
    python -m attekf.dsdlgen check        # exit 1 if one is not what the DSDL gives (ctest dsdl_current)
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Dict, List, Optional, Tuple

REPO_ROOT = Path(__file__).resolve().parents[2]
GEN_H = Path("firmware/app/dronecan/dsdl_gen.h")
GEN_C = Path("firmware/app/dronecan/dsdl_gen.c")
GEN_DUMP = Path("tests/c/app/dronecan/dsdl_dump_gen.c")
DRONECAN_VERSION = "1.0.27"   # host_tools/requirements-dronecan.lock

# The data types the node sends or receives (everything they contain comes along).
TOP_LEVEL = (
    "uavcan.protocol.NodeStatus",
    "uavcan.protocol.GetNodeInfo",
    "uavcan.protocol.RestartNode",
    "uavcan.protocol.param.GetSet",
    "uavcan.protocol.param.ExecuteOpcode",
    "uavcan.equipment.ahrs.Solution",
    "uavcan.equipment.ahrs.RawIMU",
    "uavcan.equipment.ahrs.MagneticFieldStrength2",
)


class GenError(Exception):
    """The DSDL holds something this generator does not support, or dronecan is missing."""


def _dronecan():
    try:
        import dronecan
    except ImportError as e:
        raise GenError("the dronecan package is not installed (pip install --require-hashes "
                       "-r host_tools/requirements-dronecan.lock)") from e
    if getattr(dronecan, "__version__", None) not in (None, DRONECAN_VERSION):
        v = dronecan.__version__
        raise GenError(f"dronecan {v} installed, the generated code is pinned to {DRONECAN_VERSION}")
    return dronecan


def _snake(name: str) -> str:
    """CamelCase -> camel_case (RawIMU -> raw_imu, MagneticFieldStrength2 -> magnetic_field_strength2)."""
    s = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1_\2", name)
    s = re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", s)
    return s.lower()


def c_stem(full_name: str) -> str:
    """dsdl_ + the last namespace and the type: uavcan.equipment.ahrs.Solution -> dsdl_ahrs_solution."""
    parts = full_name.split(".")
    return "dsdl_" + parts[-2] + "_" + _snake(parts[-1])


@dataclass
class Section:
    """One serialisable struct: a message, a service's request or response, or a nested type."""
    stem: str                   # C name stem: dsdl_ahrs_solution, dsdl_param_get_set_req
    full_name: str
    fields: list                # dronecan Field objects (voids included)
    union: bool
    max_bitlen: int
    public: bool                # has _encode/_decode (a top-level message or service section)
    kind: str                   # "message", "request", "response", "nested"
    dtid: Optional[int] = None
    signature: Optional[int] = None

    @property
    def empty(self) -> bool:
        return not any(f.name for f in self.fields)


def collect() -> List[Section]:
    """The sections to generate, nested types first (each once)."""
    dronecan = _dronecan()
    dsdl = dronecan.dsdl
    out: Dict[str, Section] = {}
    order: List[str] = []

    def nested(t):
        for f in t.fields:
            visit_field(f.type)
        if t.full_name not in out:
            out[t.full_name] = Section(c_stem(t.full_name), t.full_name, list(t.fields), t.union,
                                       t.get_max_bitlen(), False, "nested")
            order.append(t.full_name)

    def visit_field(ft):
        if isinstance(ft, dsdl.ArrayType):
            visit_field(ft.value_type)
        elif isinstance(ft, dsdl.CompoundType):
            if ft.kind != ft.KIND_MESSAGE:
                raise GenError(f"{ft.full_name}: a service type cannot be a field")
            nested(ft)

    sections: List[Section] = []
    for name in TOP_LEVEL:
        t = dronecan.TYPENAMES.get(name)
        if t is None:
            raise GenError(f"{name}: not in the dronecan package's DSDL")
        sig = t.get_data_type_signature()
        if t.kind == t.KIND_MESSAGE:
            for f in t.fields:
                visit_field(f.type)
            sec = Section(c_stem(name), name, list(t.fields), t.union, t.get_max_bitlen(), True,
                          "message", t.default_dtid, sig)
            if name in out:          # also nested somewhere: the public one replaces it
                out[name] = sec
            else:
                out[name] = sec
                order.append(name)
        else:
            for f in t.request_fields + t.response_fields:
                visit_field(f.type)
            for kind, fields, union, bits in (
                    ("request", t.request_fields, t.request_union, t.get_max_bitlen_request()),
                    ("response", t.response_fields, t.response_union, t.get_max_bitlen_response())):
                key = name + (".req" if kind == "request" else ".resp")
                stem = c_stem(name) + ("_req" if kind == "request" else "_resp")
                out[key] = Section(stem, name, list(fields), union, bits, True, kind, t.default_dtid, sig)
                order.append(key)
    stems = [out[k].stem for k in order]
    if len(set(stems)) != len(stems):
        raise GenError(f"C names collide: {stems}")
    return [out[k] for k in order]


# ---------------------------------------------------------------------------------------------
# C types and field code
# ---------------------------------------------------------------------------------------------
def _dsdl():
    return _dronecan().dsdl


def ctype(t) -> str:
    dsdl = _dsdl()
    if isinstance(t, dsdl.PrimitiveType):
        if t.kind == t.KIND_FLOAT:
            if t.bitlen in (16, 32):
                return "float"
            raise GenError(f"float{t.bitlen} is not supported (no double on the targets)")
        width = next(w for w in (8, 16, 32, 64) if t.bitlen <= w)
        if t.kind == t.KIND_SIGNED_INT:
            return f"int{width}_t"
        return f"uint{width}_t"
    if isinstance(t, dsdl.CompoundType):
        return c_stem(t.full_name) + "_t"
    raise GenError(f"no C type for {t}")


def len_ctype(max_size: int) -> str:
    return "uint8_t" if max_size <= 255 else "uint16_t"


def _is_empty_compound(t) -> bool:
    dsdl = _dsdl()
    return isinstance(t, dsdl.CompoundType) and not any(f.name for f in t.fields)


def _put_primitive(t, expr: str) -> str:
    dsdl = _dsdl()
    sat = t.cast_mode == t.CAST_MODE_SATURATED
    if t.kind == t.KIND_BOOLEAN:
        return f"dsdl_put_u(w, 1u, ({expr}) != 0u ? 1u : 0u);"
    if t.kind == t.KIND_FLOAT:
        if not sat:
            raise GenError("truncated floats are not supported")
        return f"dsdl_put_f{t.bitlen}(w, {expr});"
    c = ctype(t)
    width = int(re.findall(r"\d+", c)[0])
    if t.kind == t.KIND_UNSIGNED_INT:
        if sat and t.bitlen < width:
            return f"dsdl_put_u(w, {t.bitlen}u, dsdl_sat_u({expr}, {(1 << t.bitlen) - 1}u));"
        return f"dsdl_put_u(w, {t.bitlen}u, {expr});"
    lo, hi = -(1 << (t.bitlen - 1)), (1 << (t.bitlen - 1)) - 1
    if sat and t.bitlen < width:
        return f"dsdl_put_i(w, {t.bitlen}u, dsdl_sat_i({expr}, {lo}LL, {hi}LL));"
    return f"dsdl_put_i(w, {t.bitlen}u, {expr});"


def _get_primitive(t, lhs: str) -> str:
    if t.kind == t.KIND_FLOAT:
        return f"{lhs} = dsdl_get_f{t.bitlen}(r);"
    c = ctype(t)
    if t.kind == t.KIND_SIGNED_INT:
        return f"{lhs} = ({c})dsdl_get_i(r, {t.bitlen}u);"
    return f"{lhs} = ({c})dsdl_get_u(r, {'1' if t.kind == t.KIND_BOOLEAN else t.bitlen}u);"


def _put_value(t, expr: str, tao: str, ind: str) -> List[str]:
    """Code writing one value of type t (not an array)."""
    dsdl = _dsdl()
    if isinstance(t, dsdl.PrimitiveType):
        return [ind + _put_primitive(t, expr)]
    if isinstance(t, dsdl.CompoundType):
        if _is_empty_compound(t):
            return []
        return [ind + f"put_{c_stem(t.full_name)}(w, &{expr}, {tao});"]
    raise GenError(f"nested arrays are not supported: {t}")


def _get_value(t, lhs: str, tao: str, ind: str) -> List[str]:
    dsdl = _dsdl()
    if isinstance(t, dsdl.PrimitiveType):
        return [ind + _get_primitive(t, lhs)]
    if isinstance(t, dsdl.CompoundType):
        if _is_empty_compound(t):
            return []
        return [ind + f"get_{c_stem(t.full_name)}(r, &{lhs}, {tao});"]
    raise GenError(f"nested arrays are not supported: {t}")


def _field_code(f, last: bool, put: bool, ind: str, base: str = "m->") -> List[str]:
    """Code for one field of a struct; last: the field is the struct's last (tao applies)."""
    dsdl = _dsdl()
    t = f.type
    tao = "tao" if last else "0"
    if isinstance(t, dsdl.VoidType):
        return [ind + (f"dsdl_put_u(w, {t.bitlen}u, 0u);" if put else f"dsdl_skip(r, {t.bitlen}u);")]
    name = base + f.name
    if not isinstance(t, dsdl.ArrayType):
        return (_put_value if put else _get_value)(t, name, tao, ind)
    if t.mode == t.MODE_STATIC:
        n = t.max_size
        return ([ind + f"for (i = 0; i < {n}u; ++i) {{"]
                + (_put_value if put else _get_value)(t.value_type, f"{name}[i]",
                                                      f"({tao} && i + 1u == {n}u)", ind + "    ")
                + [ind + "}"])
    return (_put_dynamic if put else _get_dynamic)(t, name, last, ind)


def _dynamic_shape(t, name: str, last: bool):
    """(length bits, tail array optimisation applies, element tao, the length check is vacuous).

    The tail array optimisation: the last field of the top-level type, if its elements are at
    least a byte long, has no length prefix (the payload's length gives it). `tao` is a run-time
    flag only where the field is its struct's last one. A length check the C type cannot fail
    (uint8_t against 255) would be a warning, so it is left out."""
    n = t.max_size
    tao_ok = t.value_type.get_min_bitlen() >= 8 and last
    elem_tao = f"(tao && i + 1u == {name}_len)" if last else "0"
    full = n == (255 if len_ctype(n) == "uint8_t" else 65535)
    return n.bit_length(), tao_ok, ("0" if tao_ok else elem_tao), full


def _put_dynamic(t, name: str, last: bool, ind: str) -> List[str]:
    n = t.max_size
    len_bits, tao_ok, elem_tao, full = _dynamic_shape(t, name, last)
    lines: List[str] = []
    if not full:
        lines += [ind + f"if ({name}_len > {n}u) {{", ind + "    w->error = 1u;",
                  ind + "    return;", ind + "}"]
    if tao_ok:
        lines += [ind + "if (!tao) {", ind + f"    dsdl_put_u(w, {len_bits}u, {name}_len);",
                  ind + "}"]
    else:
        lines.append(ind + f"dsdl_put_u(w, {len_bits}u, {name}_len);")
    lines.append(ind + f"for (i = 0; i < {name}_len; ++i) {{")
    lines += _put_value(t.value_type, f"{name}[i]", elem_tao, ind + "    ")
    lines.append(ind + "}")
    return lines


def _get_tail(t, name: str, ind: str) -> List[str]:
    """The tail array: as many elements as the payload holds."""
    n = t.max_size
    return ([ind + "if (tao) {",
             ind + "    /* tail array: as many elements as the payload holds */",
             ind + f"    {name}_len = 0u;",
             ind + f"    while (dsdl_left(r) >= 8u && {name}_len < {n}u) {{"]
            + _get_value(t.value_type, f"{name}[{name}_len]", "0", ind + "        ")
            + [ind + f"        ++{name}_len;",
               ind + "    }",
               ind + "    if (dsdl_left(r) >= 8u) {",
               ind + "        r->error = 1u; /* more elements than the array holds */",
               ind + "    }",
               ind + "} else {"])


def _get_dynamic(t, name: str, last: bool, ind: str) -> List[str]:
    n = t.max_size
    len_bits, tao_ok, elem_tao, full = _dynamic_shape(t, name, last)
    lines = _get_tail(t, name, ind) if tao_ok else []
    sub = ind + "    " if tao_ok else ind
    lines.append(sub + f"{name}_len = ({len_ctype(n)})dsdl_get_u(r, {len_bits}u);")
    if not full:
        lines += [sub + f"if ({name}_len > {n}u) {{", sub + "    r->error = 1u;",
                  sub + "    return;", sub + "}"]
    lines.append(sub + f"for (i = 0; i < {name}_len; ++i) {{")
    lines += _get_value(t.value_type, f"{name}[i]", elem_tao, sub + "    ")
    lines.append(sub + "}")
    if tao_ok:
        lines.append(ind + "}")
    return lines


def _needs_index(sec: Section) -> bool:
    dsdl = _dsdl()
    return any(isinstance(f.type, dsdl.ArrayType) for f in sec.fields)


def _tag_bits(sec: Section) -> int:
    return max(len(sec.fields) - 1, 1).bit_length()


def _struct(sec: Section) -> List[str]:
    dsdl = _dsdl()
    kind = {"message": f"message {sec.dtid}", "request": f"request of service {sec.dtid}",
            "response": f"response of service {sec.dtid}", "nested": "nested type"}[sec.kind]
    lines = [f"/* {sec.full_name} ({kind}) */"]
    if sec.union:
        for k, f in enumerate(sec.fields):
            lines.append(f"#define {sec.stem.upper()}_{f.name.upper()} {k}u /* union tag */")
    lines.append("typedef struct {")
    if sec.union:
        lines.append(f"    uint8_t tag; /* {sec.stem.upper()}_*: the member that is set */")
    for f in sec.fields:
        t = f.type
        if isinstance(t, dsdl.VoidType) or _is_empty_compound(t):
            continue
        if isinstance(t, dsdl.ArrayType):
            lines.append(f"    {ctype(t.value_type)} {f.name}[{t.max_size}]; /* {t.get_normalized_definition()} */")
            if t.mode == t.MODE_DYNAMIC:
                lines.append(f"    {len_ctype(t.max_size)} {f.name}_len;")
        else:
            lines.append(f"    {ctype(t)} {f.name}; /* {t.get_normalized_definition()} */")
    lines.append(f"}} {sec.stem}_t;")
    return lines


def _body(sec: Section, put: bool) -> List[str]:
    fn = "put" if put else "get"
    sig = (f"static void put_{sec.stem}(dsdl_writer_t *w, const {sec.stem}_t *m, int tao)" if put else
           f"static void get_{sec.stem}(dsdl_reader_t *r, {sec.stem}_t *m, int tao)")
    lines = [sig, "{"]
    if _needs_index(sec):
        lines.append("    uint32_t i;")
    if sec.union:
        tb = _tag_bits(sec)
        if put:
            lines.append(f"    dsdl_put_u(w, {tb}u, m->tag);")
        else:
            lines.append(f"    m->tag = (uint8_t)dsdl_get_u(r, {tb}u);")
        lines.append("    switch (m->tag) {")
        for k, f in enumerate(sec.fields):
            lines.append(f"    case {k}u:")
            lines += _field_code(f, True, put, "        ")
            lines.append("        break;")
        lines.append("    default:")
        lines.append("        " + ("w" if put else "r") + "->error = 1u; /* no such member */")
        lines.append("        break;")
        lines.append("    }")
    else:
        n = len(sec.fields)
        for k, f in enumerate(sec.fields):
            lines += _field_code(f, k == n - 1, put, "    ")
    lines.append("    (void)tao;")
    lines.append("}")
    return lines


def _max_bytes(sec: Section) -> int:
    return (sec.max_bitlen + 7) // 8


def header_text(secs: List[Section]) -> str:
    out = [
        "/*",
        f" * dsdl_gen.h - GENERATED by host_tools/attekf/dsdlgen.py from the DSDL of the dronecan",
        f" * {DRONECAN_VERSION} Python package; do not edit (python -m attekf.dsdlgen generate).",
        " *",
        " * One struct per DroneCAN data type the node uses, and for each message and service section",
        " *     int <stem>_encode(const <stem>_t *m, uint8_t *buf, size_t size): bytes written, or -1",
        " *     int <stem>_decode(<stem>_t *m, const uint8_t *buf, size_t len): 0, or -1 if malformed",
        " * buf holds the transfer payload (no CRC, no tail bytes: dcan_transfer.h adds those). The",
        " * last field of the payload is written with the tail array optimisation; a dynamic array",
        " * has a _len member; a union has a tag member (the <STEM>_<MEMBER> constants). Floats are",
        " * float16/float32 on the wire and float here.",
        " */",
        "#ifndef DSDL_GEN_H",
        "#define DSDL_GEN_H",
        "",
        "#include <stddef.h>",
        "#include <stdint.h>",
        "",
        "#ifdef __cplusplus",
        'extern "C" {',
        "#endif",
        "",
    ]
    seen_ids = set()
    for sec in secs:
        if sec.public and sec.full_name not in seen_ids:
            seen_ids.add(sec.full_name)
            base = c_stem(sec.full_name).upper()
            out.append(f"#define {base}_ID {sec.dtid}u")
            out.append(f"#define {base}_SIGNATURE 0x{sec.signature:016X}ull")
        if sec.public:
            out.append(f"#define {sec.stem.upper()}_MAX_BYTES {_max_bytes(sec)}u")
        if sec.empty:
            if sec.public:
                out.append(f"/* {sec.full_name} {sec.kind}: no fields (an empty payload) */")
                out.append("")
            continue
        out += _struct(sec)
        if sec.public:
            out.append(f"int {sec.stem}_encode(const {sec.stem}_t *m, uint8_t *buf, size_t size);")
            out.append(f"int {sec.stem}_decode({sec.stem}_t *m, const uint8_t *buf, size_t len);")
        out.append("")
    out += ["#ifdef __cplusplus", "}", "#endif", "", "#endif /* DSDL_GEN_H */", ""]
    return "\n".join(out)


def source_text(secs: List[Section]) -> str:
    out = [
        "/*",
        f" * dsdl_gen.c - GENERATED by host_tools/attekf/dsdlgen.py from the DSDL of the dronecan",
        f" * {DRONECAN_VERSION} Python package; do not edit (python -m attekf.dsdlgen generate).",
        " * Serialisation of the types of dsdl_gen.h, on the bit helpers of dsdl_bits.h.",
        " */",
        '#include "dsdl_gen.h"',
        "",
        '#include "dsdl_bits.h"',
        "",
    ]
    for sec in secs:
        if sec.empty:
            continue
        out += _body(sec, True) + [""] + _body(sec, False) + [""]
        if sec.public:
            out += [
                f"int {sec.stem}_encode(const {sec.stem}_t *m, uint8_t *buf, size_t size)",
                "{",
                "    dsdl_writer_t w;",
                "    dsdl_writer_init(&w, buf, size);",
                f"    put_{sec.stem}(&w, m, 1);",
                "    return dsdl_writer_end(&w);",
                "}",
                "",
                f"int {sec.stem}_decode({sec.stem}_t *m, const uint8_t *buf, size_t len)",
                "{",
                "    dsdl_reader_t r;",
                "    dsdl_reader_init(&r, buf, len);",
                f"    get_{sec.stem}(&r, m, 1);",
                "    return dsdl_reader_end(&r);",
                "}",
                "",
            ]
    return "\n".join(out)


# ---------------------------------------------------------------------------------------------
def targets(root: Path) -> Dict[Path, str]:
    from .dsdldump import dump_text  # the test-side printer (imports this module)

    secs = collect()
    return {root / GEN_H: header_text(secs), root / GEN_C: source_text(secs),
            root / GEN_DUMP: dump_text(secs)}


def main(argv: Optional[List[str]] = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m attekf.dsdlgen",
        description="Generate (or check) the node's DroneCAN serialisation (firmware/app/dronecan/"
                    "dsdl_gen.[ch]) and the tests' printer from the DSDL of the dronecan package.")
    ap.add_argument("action", choices=("generate", "check"),
                    help="generate: rewrite the files; check: exit 1 if any is not current")
    ap.add_argument("--root", default=str(REPO_ROOT), help="source tree (default: this one)")
    args = ap.parse_args(argv)
    try:
        tg = targets(Path(args.root))
    except GenError as e:
        print(f"dsdlgen: {e}", file=sys.stderr)
        return 1
    stale = [p for p, text in tg.items() if not p.is_file() or p.read_text(encoding="utf-8") != text]
    if args.action == "check":
        for p in stale:
            print(f"dsdlgen: {p} is not current: run python -m attekf.dsdlgen generate", file=sys.stderr)
        return 1 if stale else 0
    for p in stale:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(tg[p], encoding="utf-8")
        print(f"dsdlgen: wrote {p}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
