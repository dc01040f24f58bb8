"""Every number of Hokuyo's SCIP 2.0 protocol (URG/UTM laser range finders), once, with its source.

Sources (docs/protocols/hokuyo.md has the details):

- [scip] Hokuyo Automatic, "URG Series Communication Protocol Specification SCIP 2.0" and the
  UTM-30LX-EW protocol document: line format, the 6-bit character encoding, the sum character,
  command formats and status codes of VV, PP, II, BM, QT, RS, TM, MD/MS, GD/GS.
- [cap] public captures of a real URG-04LX-UG01 (firmware 3.4.03): the VV reply with its sums
  (`VEND:Hokuyo Automatic Co.,Ltd.;[`, `PROT:SCIP 2.0;N`, `SERI:H1510998;V`) and `BM` -> `02R`.
- [lx] hokuyolx 0.9.0 (PyPI, a SCIP 2.0 client): PP keys it reads, the TM0/TM1/TM2 time commands,
  the reply statuses it knows ('0E' command not defined, '10' denied, '0M' unstable).

Values in the protocol's own units carry the unit in their name (`_MM`, `_MS`, `_RPM`).
"""

from __future__ import annotations

from typing import Final

# --- link [scip]: USB-ACM (a serial port whose baud rate does not matter) or TCP (UTM-30LX-EW)
BAUD_RATE: Final = 115200           # what the host opens a USB-ACM port with (ignored by the device)
TCP_PORT: Final = 10940             # UTM-30LX-EW Ethernet port (default address 192.168.0.10)

# --- line format [scip "Communication format"]
LF: Final = 0x0A                    # line end; a reply ends with an empty line (LF LF)
CR: Final = 0x0D                    # accepted as a command terminator as well as LF
TERMINATOR: Final = b"\n"
BLOCK_END: Final = b"\n\n"
LINE_DATA_MAX: Final = 64           # data characters per line before the sum and LF
STRING_MAX: Final = 16              # the optional ";string" a command may carry, echoed back

# --- character encoding [scip "Data encoding"]: 6-bit groups, most significant first, each + 0x30
ENCODE_OFFSET: Final = 0x30
ENCODE_BITS: Final = 6
CHAR_MIN: Final = 0x30
CHAR_MAX: Final = 0x30 + 63         # 0x6F
ENC2_MAX: Final = (1 << 12) - 1     # 4095: largest value in 2 characters (MS, GS)
ENC3_MAX: Final = (1 << 18) - 1     # 262143: largest value in 3 characters (MD, GD)
TIMESTAMP_CHARS: Final = 4          # time stamps: 4 characters, 24-bit millisecond counter
TIMESTAMP_MODULO: Final = 1 << 24

# --- sum [scip "Check sum"]: add the line's data bytes, keep the low 6 bits, add 0x30. Parameter
# lines (VV/PP/II) "KEY:value;S": the sum covers "KEY:value" without the ';' [cap, lx].
SUM_MASK: Final = 0x3F

# --- commands [scip]
CMD_VV: Final = b"VV"               # version: VEND PROD FIRM PROT SERI
CMD_PP: Final = b"PP"               # parameters: MODL DMIN DMAX ARES AMIN AMAX AFRT SCAN
CMD_II: Final = b"II"               # status: MODL LASR SCSP MESM SBPS TIME STAT
CMD_BM: Final = b"BM"               # laser on
CMD_QT: Final = b"QT"               # laser off, stops MD/MS
CMD_RS: Final = b"RS"               # reset: laser off, timer 0, settings to defaults
CMD_TM: Final = b"TM"               # time adjust: TM0 enter, TM1 read the time, TM2 leave [lx]
CMD_SCIP2: Final = b"SCIP2.0"       # switch a SCIP 1.1 sensor to SCIP 2.0
CMD_MD: Final = b"MD"               # multi-scan, 3-character data
CMD_MS: Final = b"MS"               # multi-scan, 2-character data
CMD_GD: Final = b"GD"               # one scan, 3-character data
CMD_GS: Final = b"GS"               # one scan, 2-character data
ENCODING_CHARS: Final = {CMD_MD: 3, CMD_GD: 3, CMD_MS: 2, CMD_GS: 2}
# MD/MS parameters: start step (4 digits), end step (4), cluster count (2), scan interval (1),
# number of scans (2; 00 = unlimited) [scip]. GD/GS: start (4), end (4), cluster (2).
MD_PARAM_DIGITS: Final = 13
GD_PARAM_DIGITS: Final = 10
SCANS_UNLIMITED: Final = 0

# --- statuses [scip; lx statuses.py]: two characters, then the sum character
STATUS_OK: Final = b"00"
STATUS_SCAN: Final = b"99"          # a scan of an MD/MS stream
STATUS_BM_ALREADY_ON: Final = b"02"   # BM: the laser was already on [cap]
STATUS_BAD_START: Final = b"01"     # MD/GD: start step not a number
STATUS_BAD_END: Final = b"02"       # MD/GD: end step not a number
STATUS_BAD_CLUSTER: Final = b"03"   # MD/GD: cluster count not a number
STATUS_END_OUT_OF_RANGE: Final = b"04"
STATUS_END_BEFORE_START: Final = b"05"
STATUS_BAD_INTERVAL: Final = b"06"  # MD: scan interval not a number
STATUS_BAD_SCANS: Final = b"07"     # MD: number of scans not a number
STATUS_TM_BAD_CODE: Final = b"01"   # TM: control code not 0, 1, 2 [lx]
STATUS_TM_ALREADY_IN: Final = b"02"
STATUS_TM_ALREADY_OUT: Final = b"03"
STATUS_TM_NOT_IN: Final = b"04"
STATUS_UNDEFINED: Final = b"0E"     # command not defined [lx]
STATUS_DENIED: Final = b"10"        # denied (e.g. GD with the laser off) [lx]
STATUS_UNSTABLE: Final = b"0M"      # scan skipped: unstable condition [lx]

# --- URG-04LX [scip PP of the URG-04LX]: 240 deg over steps 44..725 of 1024 per turn, front 384,
# 600 rpm (100 ms per scan), distances 20..5600 mm (rated 4 m)
URG04_MODL: Final = "URG-04LX(Hokuyo Automatic Co.,Ltd.)"
URG04_DMIN_MM: Final = 20
URG04_DMAX_MM: Final = 5600
URG04_RATED_MM: Final = 4000
URG04_ARES: Final = 1024
URG04_AMIN: Final = 44
URG04_AMAX: Final = 725
URG04_AFRT: Final = 384
URG04_SCAN_RPM: Final = 600
# URG-04LX error codes are values below DMIN; 1 is "reflected light of low intensity" (no echo).
NO_ECHO_CODE: Final = 1

# --- UTM-30LX [scip UTM-30LX]: 270 deg over steps 0..1080 of 1440, front 540, 2400 rpm (25 ms),
# distances 23..60000 mm (rated 30 m)
UTM30_MODL: Final = "UTM-30LX"
UTM30_DMIN_MM: Final = 23
UTM30_DMAX_MM: Final = 60000
UTM30_RATED_MM: Final = 30000
UTM30_ARES: Final = 1440
UTM30_AMIN: Final = 0
UTM30_AMAX: Final = 1080
UTM30_AFRT: Final = 540
UTM30_SCAN_RPM: Final = 2400

# rated range of a model, by its MODL text [scip product pages]: echoes beyond it are not guaranteed
RATED_RANGE_MM: Final = {"URG-04LX": URG04_RATED_MM, "UTM-30LX": UTM30_RATED_MM}
