/* The fracid drive protocol for the C firmware: GENERATED from crates/drive/src/protocol/spec.rs
 * (`DRIVE_REGEN_PROTOCOL=1 cargo test -p drive --lib spec`); do not edit. A test fails when
 * this file differs from the table. */
#ifndef FW_PROTOCOL_H
#define FW_PROTOCOL_H

/* versions, counts, limits, flags */
#define FW_PROTO_VERSION 3u /* protocol version (low nibble of the first body byte) */
#define FW_MAJOR 1u /* firmware version reported in HELLO_REPLY: major */
#define FW_MINOR 3u /* and minor */
#define FW_N_CHANNELS 3u /* channels per sample (u, y, i) */
#define FW_MAX_BLOCK 66u /* samples per DATA block at most */
#define FW_MAX_DFT_SAMPLES 4194304ul /* longest sine window with the DFT, samples */
#define FW_SINE_STREAM 1u /* START_SINE flag: stream DATA */
#define FW_SINE_DFT 2u /* START_SINE flag: the DFT on the drive */
#define FW_CTRL_FORMAT 1u /* controller format 1: sections */
#define FW_CTRL_FORMAT_TAPS 2u /* controller format 2: sections and delay taps */
#define FW_MAX_SECTIONS_V1 24u /* sections of a format-1 controller at most */
#define FW_MAX_SECTIONS 48u /* sections of a format-2 controller at most */
#define FW_MAX_TAPS 8u /* delay taps of a format-2 controller at most */

/* NAK codes, faults, end reasons, states */
#define FW_NAK_UNKNOWN_TYPE 1u /* NAK: unknown type */
#define FW_NAK_BAD_LENGTH 2u /* NAK: bad length */
#define FW_NAK_BAD_VALUE 3u /* NAK: a field out of range (detail: its offset) */
#define FW_NAK_BUSY 4u /* NAK: a run is active */
#define FW_NAK_NOT_CONFIGURED 5u /* NAK: no configuration yet */
#define FW_NAK_FAULT 6u /* NAK: a fault is latched (detail: its code) */
#define FW_NAK_VERSION 7u /* NAK: version mismatch */
#define FW_NAK_NO_CONTROLLER 8u /* NAK: START_LOOP without a complete controller */
#define FW_FAULT_NONE 0u /* no fault */
#define FW_FAULT_ESTOP 1u /* emergency stop */
#define FW_FAULT_KEEPALIVE 2u /* keepalive expired */
#define FW_FAULT_SPEED 3u /* speed trip */
#define FW_FAULT_CURRENT 4u /* current trip */
#define FW_END_COMPLETE 0u /* run ended: ran to the end */
#define FW_END_STOPPED 1u /* run ended: host STOP */
#define FW_END_ESTOP 2u /* run ended: ESTOP */
#define FW_END_KEEPALIVE 3u /* run ended: keepalive expired */
#define FW_END_LIMIT 4u /* run ended: speed or current trip */
#define FW_STATE_UNCONFIGURED 0u /* state: not configured */
#define FW_STATE_IDLE 1u /* state: configured, idle */
#define FW_STATE_RUNNING 2u /* state: a run is active */
#define FW_STATE_FAULT 3u /* state: a fault is latched */

/* message types */
#define FW_T_HELLO 0x01u
#define FW_T_CONFIGURE 0x02u
#define FW_T_START_PRBS 0x03u
#define FW_T_START_SINE 0x04u
#define FW_T_STOP 0x05u
#define FW_T_ESTOP 0x06u
#define FW_T_STATUS 0x07u
#define FW_T_KEEPALIVE 0x08u
#define FW_T_END_QUERY 0x09u
#define FW_T_LOAD_CTRL 0x0Au
#define FW_T_LOAD_SECTION 0x0Bu
#define FW_T_START_LOOP 0x0Cu
#define FW_T_ACK 0x80u
#define FW_T_HELLO_REPLY 0x81u
#define FW_T_STATUS_REPLY 0x87u
#define FW_T_NAK 0x8Fu
#define FW_T_DATA 0x90u
#define FW_T_STREAM_END 0x91u
#define FW_T_SINE_RESULT 0x92u

/* payload lengths (DATA: without its samples) */
#define FW_LEN_HELLO 0u
#define FW_LEN_CONFIGURE 26u
#define FW_LEN_START_PRBS 22u
#define FW_LEN_START_SINE 14u
#define FW_LEN_STOP 0u
#define FW_LEN_ESTOP 0u
#define FW_LEN_STATUS 0u
#define FW_LEN_KEEPALIVE 2u
#define FW_LEN_END_QUERY 2u
#define FW_LEN_LOAD_CTRL 12u
#define FW_LEN_LOAD_SECTION 10u
#define FW_LEN_START_LOOP 12u
#define FW_LEN_ACK 8u
#define FW_LEN_HELLO_REPLY 12u
#define FW_LEN_STATUS_REPLY 16u
#define FW_LEN_NAK 4u
#define FW_LEN_DATA 8u
#define FW_LEN_DATA_SAMPLE 6u
#define FW_LEN_STREAM_END 14u
#define FW_LEN_SINE_RESULT 38u

/* field offsets in the payload */
#define FW_OFF_CONFIGURE_SAMPLE_RATE_HZ 0u
#define FW_OFF_CONFIGURE_BLOCK_SAMPLES 4u
#define FW_OFF_CONFIGURE_RESERVED 5u
#define FW_OFF_CONFIGURE_KEEPALIVE_MS 6u
#define FW_OFF_CONFIGURE_SCALE_U_UV 8u
#define FW_OFF_CONFIGURE_SCALE_Y_URAD_S 12u
#define FW_OFF_CONFIGURE_SCALE_I_UA 16u
#define FW_OFF_CONFIGURE_U_LIMIT 20u
#define FW_OFF_CONFIGURE_Y_LIMIT 22u
#define FW_OFF_CONFIGURE_I_LIMIT 24u
#define FW_OFF_START_PRBS_ORDER 0u
#define FW_OFF_START_PRBS_RESERVED 1u
#define FW_OFF_START_PRBS_TAPS 2u
#define FW_OFF_START_PRBS_SEED 6u
#define FW_OFF_START_PRBS_CLOCK_SAMPLES 10u
#define FW_OFF_START_PRBS_AMPLITUDE 12u
#define FW_OFF_START_PRBS_OFFSET 14u
#define FW_OFF_START_PRBS_PERIODS 16u
#define FW_OFF_START_PRBS_SETTLE_SAMPLES 18u
#define FW_OFF_START_SINE_FREQ_MHZ 0u
#define FW_OFF_START_SINE_AMPLITUDE 4u
#define FW_OFF_START_SINE_OFFSET 6u
#define FW_OFF_START_SINE_SETTLE_CYCLES 8u
#define FW_OFF_START_SINE_CYCLES 10u
#define FW_OFF_START_SINE_FLAGS 12u
#define FW_OFF_START_SINE_RESERVED 13u
#define FW_OFF_KEEPALIVE_RUN_ID 0u
#define FW_OFF_END_QUERY_RUN_ID 0u
#define FW_OFF_LOAD_CTRL_FORMAT 0u
#define FW_OFF_LOAD_CTRL_N_SECTIONS 1u
#define FW_OFF_LOAD_CTRL_N_TAPS 2u
#define FW_OFF_LOAD_CTRL_RESERVED 3u
#define FW_OFF_LOAD_CTRL_D_Q24 4u
#define FW_OFF_LOAD_CTRL_DINV_Q16 8u
#define FW_OFF_LOAD_SECTION_INDEX 0u
#define FW_OFF_LOAD_SECTION_RESERVED 1u
#define FW_OFF_LOAD_SECTION_A_Q30 2u
#define FW_OFF_LOAD_SECTION_G_Q24 6u
#define FW_OFF_START_LOOP_R0 0u
#define FW_OFF_START_LOOP_R1 2u
#define FW_OFF_START_LOOP_PRE_SAMPLES 4u
#define FW_OFF_START_LOOP_TOTAL_SAMPLES 8u
#define FW_OFF_ACK_ACKED_TYPE 0u
#define FW_OFF_ACK_RESERVED 1u
#define FW_OFF_ACK_RUN_ID 2u
#define FW_OFF_ACK_TOTAL_SAMPLES 4u
#define FW_OFF_HELLO_REPLY_PROTO_VERSION 0u
#define FW_OFF_HELLO_REPLY_FW_MAJOR 1u
#define FW_OFF_HELLO_REPLY_FW_MINOR 2u
#define FW_OFF_HELLO_REPLY_N_CHANNELS 3u
#define FW_OFF_HELLO_REPLY_MAX_BLOCK_SAMPLES 4u
#define FW_OFF_HELLO_REPLY_RESERVED 5u
#define FW_OFF_HELLO_REPLY_BOOT_ID 6u
#define FW_OFF_HELLO_REPLY_MAX_SAMPLE_RATE_HZ 8u
#define FW_OFF_STATUS_REPLY_STATE 0u
#define FW_OFF_STATUS_REPLY_FAULT 1u
#define FW_OFF_STATUS_REPLY_RUN_ID 2u
#define FW_OFF_STATUS_REPLY_SAMPLES_DONE 4u
#define FW_OFF_STATUS_REPLY_BLOCKS_DROPPED 8u
#define FW_OFF_STATUS_REPLY_BOOT_ID 10u
#define FW_OFF_STATUS_REPLY_RX_ERRORS 12u
#define FW_OFF_STATUS_REPLY_CLAMPED 14u
#define FW_OFF_NAK_NAK_TYPE 0u
#define FW_OFF_NAK_CODE 1u
#define FW_OFF_NAK_DETAIL 2u
#define FW_OFF_DATA_RUN_ID 0u
#define FW_OFF_DATA_FIRST_INDEX 2u
#define FW_OFF_DATA_N 6u
#define FW_OFF_DATA_FLAGS 7u
#define FW_OFF_DATA_SAMPLE_U 0u /* in each sample */
#define FW_OFF_DATA_SAMPLE_Y 2u /* in each sample */
#define FW_OFF_DATA_SAMPLE_I 4u /* in each sample */
#define FW_OFF_STREAM_END_RUN_ID 0u
#define FW_OFF_STREAM_END_REASON 2u
#define FW_OFF_STREAM_END_RESERVED 3u
#define FW_OFF_STREAM_END_TOTAL_SAMPLES 4u
#define FW_OFF_STREAM_END_SAMPLES_SENT 8u
#define FW_OFF_STREAM_END_BLOCKS_DROPPED 12u
#define FW_OFF_SINE_RESULT_RUN_ID 0u
#define FW_OFF_SINE_RESULT_N 2u
#define FW_OFF_SINE_RESULT_U_RE 6u
#define FW_OFF_SINE_RESULT_U_IM 10u
#define FW_OFF_SINE_RESULT_Y_RE 14u
#define FW_OFF_SINE_RESULT_Y_IM 18u
#define FW_OFF_SINE_RESULT_U_MEAN 22u
#define FW_OFF_SINE_RESULT_U_RAMP 26u
#define FW_OFF_SINE_RESULT_Y_MEAN 30u
#define FW_OFF_SINE_RESULT_Y_RAMP 34u

#endif
