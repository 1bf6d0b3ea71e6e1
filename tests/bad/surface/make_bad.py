#!/usr/bin/env python3
"""Writes the malformed height maps of tests/bad/surface (Python standard library only).

Run from the repository root: python3 tests/bad/surface/make_bad.py
"""
import hashlib
import math
import struct
import zipfile
from pathlib import Path

OUT = Path(__file__).resolve().parent
NX, NY = 50, 80  # 4000 points


def md5(b: bytes) -> str:
    return hashlib.md5(b).hexdigest()


def main_xml(data_md5: str, *, dtype="F", px="8.71e-7", py="8.71e-7", feature="SUR", valid_md5=None) -> str:
    valid = ""
    if valid_md5 is not None:
        valid = f"<ValidPointsLink>bindata/valid.bin</ValidPointsLink><MD5ChecksumValidPoints>{valid_md5}</MD5ChecksumValidPoints>"
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2">
  <Record1><Revision>ISO25178-72:2017/DAM1</Revision><FeatureType>{feature}</FeatureType>
    <Axes>
      <CX><AxisType>I</AxisType><DataType>D</DataType><Increment>{px}</Increment><Offset>0</Offset></CX>
      <CY><AxisType>I</AxisType><DataType>D</DataType><Increment>{py}</Increment><Offset>0</Offset></CY>
      <CZ><AxisType>A</AxisType><DataType>{dtype}</DataType><Increment>1</Increment><Offset>0</Offset></CZ>
    </Axes></Record1>
  <Record2><Date>2026-01-01T00:00:00+00:00</Date><Instrument><Manufacturer>tests/bad</Manufacturer><Model>make_bad.py</Model><Serial>none</Serial><Version>1</Version></Instrument>
    <ProbingSystem><Type>Software</Type><Identification>make_bad.py</Identification></ProbingSystem></Record2>
  <Record3><MatrixDimension><SizeX>{NX}</SizeX><SizeY>{NY}</SizeY><SizeZ>1</SizeZ></MatrixDimension>
    <DataLink><PointDataLink>bindata/data.bin</PointDataLink><MD5ChecksumPointData>{data_md5}</MD5ChecksumPointData>{valid}</DataLink></Record3>
  <Record4><ChecksumFile>md5checksum.hex</ChecksumFile></Record4>
</p:ISO5436_2>
"""


def heights():
    return [1e-7 * math.sin(0.3 * (k % NX)) * math.cos(0.2 * (k // NX)) for k in range(NX * NY)]


def f32(values) -> bytes:
    return struct.pack(f"<{len(values)}f", *values)


def archive(name: str, main: str, data: bytes | None, *, checksum: str | None = None, valid: bytes | None = None):
    main_b = main.encode()
    with zipfile.ZipFile(OUT / name, "w", zipfile.ZIP_DEFLATED) as z:
        for member, content in (
            ("main.xml", main_b),
            ("md5checksum.hex", f"{checksum or md5(main_b)} *main.xml\n".encode()),
            ("bindata/data.bin", data),
            ("bindata/valid.bin", valid),
        ):
            if content is not None:
                info = zipfile.ZipInfo(member, date_time=(1980, 1, 1, 0, 0, 0))
                z.writestr(info, content, zipfile.ZIP_DEFLATED)


good = f32(heights())
archive("good.x3p", main_xml(md5(good)), good)
whole = (OUT / "good.x3p").read_bytes()
(OUT / "truncated.x3p").write_bytes(whole[: len(whole) // 2])
(OUT / "good.x3p").unlink()
(OUT / "not_a_zip.x3p").write_text("this is not an X3P archive\n")
short = good[: 3999 * 4]
archive("point_count.x3p", main_xml(md5(short)), short)
archive("zero_pitch.x3p", main_xml(md5(good), px="0"), good)
archive("negative_pitch.x3p", main_xml(md5(good), py="-8.71e-7"), good)
nan = f32([math.nan] * (NX * NY))
archive("all_invalid.x3p", main_xml(md5(nan)), nan)
tampered = bytearray(good)
tampered[400] ^= 0x40
archive("data_checksum.x3p", main_xml(md5(good)), bytes(tampered))
archive("main_checksum.x3p", main_xml(md5(good)), good, checksum=md5(main_xml(md5(good), px="8.7e-7").encode()))
archive("missing_data.x3p", main_xml(md5(good)), None)
i16 = struct.pack(f"<{NX * NY}h", *[int(round(h * 1e9)) for h in heights()])
bits = b"\xff" * 100  # 800 points' bits instead of 4000
archive("valid_short.x3p", main_xml(md5(i16), dtype="I", valid_md5=md5(bits)), i16, valid=bits)
archive("profile.x3p", main_xml(md5(good), feature="PRF"), good)
archive("bad_xml.x3p", main_xml(md5(good)).replace("</Record1>", "</Record>"), good)

rows = [[f"{1e-3 * ((3 * i + 7 * j) % 11):.4f}" for i in range(4)] for j in range(3)]
text = "\n".join(",".join(r) for r in rows) + "\n"
(OUT / "negative_pitch.csv").write_text("# pitch_um = -0.5\n# height_unit = um\n" + text)
(OUT / "all_invalid.csv").write_text("# pitch_um = 0.5\n# height_unit = um\nNaN,NaN,,NaN\n,,,\nnan,NaN,NaN,NaN\n")
(OUT / "ragged.csv").write_text("# pitch_um = 0.5\n# height_unit = um\n1,2,3,4\n5,6,7,8\n9,10,11\n")
(OUT / "bad_number.csv").write_text("# pitch_um = 0.5\n# height_unit = um\n1,2,3,4\n5,1.2.3,7,8\n")
(OUT / "no_pitch.csv").write_text("# height_unit = um\n" + text)


def tiff_u16(width: int, height: int) -> bytes:
    """A minimal uncompressed little-endian 16-bit grey TIFF."""
    pixels = struct.pack(f"<{width * height}H", *[(k * 37) % 65536 for k in range(width * height)])
    entries = [
        (256, 3, 1, width), (257, 3, 1, height), (258, 3, 1, 16), (259, 3, 1, 1), (262, 3, 1, 1),
        (273, 4, 1, 8), (277, 3, 1, 1), (278, 3, 1, height), (279, 4, 1, len(pixels)),
    ]
    ifd_offset = 8 + len(pixels)
    ifd = struct.pack("<H", len(entries))
    for tag, typ, count, value in entries:
        ifd += struct.pack("<HHI", tag, typ, count) + (struct.pack("<HH", value, 0) if typ == 3 else struct.pack("<I", value))
    ifd += struct.pack("<I", 0)
    return b"II" + struct.pack("<HI", 42, ifd_offset) + pixels + ifd


(OUT / "integer.tif").write_bytes(tiff_u16(16, 12))
