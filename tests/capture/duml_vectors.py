"""The verified DUML test vectors of shared/research/dji-telemetry.md section 1.4 (hex, as published)."""

VECTORS = {
    "1_rc_channel_params_get": "55 0d 04 33 0a 06 eb 34 40 06 01 74 24",
    "2_rc_simulate_flight_mode_set": "55 0e 04 66 0a 06 eb 34 40 06 24 01 d9 ec",
    "3_mini_rc_ping_seq3": "55 0d 04 33 0a 0e 03 00 40 06 01 f4 4a",
    "3_mini_rc_seq2": "55 0d 04 33 0a 0e 02 00 40 06 27 84 05",
    "3_mini_rc_seq4": "55 0d 04 33 0a 0e 04 00 40 06 27 1c 3e",
    "3_mini_rc_seq5": "55 0d 04 33 0a 0e 05 00 40 06 01 6c 71",
    "4_fc_response": "55 0e 04 66 03 0a 9d a5 80 03 df 00 a7 92",
    "5_gimbal_to_pc": "55 0f 04 a2 04 0a 71 92 00 04 08 01 11 2c 70",
    "6_pc_idx1_to_dm3xx": "55 0e 04 66 2a 28 de 2f 40 00 4f 01 54 c8",
    "7_osd_general_p3x": ("55 3f 04 8f 03 09 2a 01 00 03 43 1c 88 da 9d cb bb d4 3f 9d 9a 0e f5 3b 5e ee 3f 00 00 00"
                          " 00"
                          " 01 00 00 00 c4 ff cf ff df 04 01 00 11 50 84 00 05 00 00 00 61 00 00 00 00 1e 8a 09 02 00"
                          " be 90"),
    "8_gimbal_params": "55 19 04 e4 04 03 e0 15 00 04 05 30 ff da fe 45 ff 80 00 00 00 20 01 0d 11",
    "9_gimbal_params_yaw130": "55 19 04 e4 04 03 f8 3f 00 04 05 00 00 00 00 14 05 80 00 00 00 20 01 d1 58",
    "10_date_time_set": "55 14 04 6d 02 03 ac 06 40 03 1c 15 1d 26 e1 07 0c 14 46 93",
    "10_date_time_set_response": "55 14 04 6d 03 02 ac 06 80 03 1c 15 1d 26 e1 07 0c 14 8c 1b",
}

# Vector 11 (OSD Home Point, 81 bytes) is published only in part: its header and the first 32 payload bytes.
VECTOR_11_HEADER_AND_PAYLOAD_PREFIX = ("55 51 04 09 03 09 84 00 00 03 44"
                                       " 00 00 00 00 00 6a 28 41 00 00 00 00 00 6a 28 41"
                                       " 40 b5 ed c3 46 20 3c 00 e0 08 00 15 00 00 db 00")


def frame(name: str) -> bytes:
    return bytes.fromhex(VECTORS[name])
