"""SICK LMS2xx (LMS200/291) laser driver: RS-232/422 telegrams with CRC-16 (work in progress)."""
