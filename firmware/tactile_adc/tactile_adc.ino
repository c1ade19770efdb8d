// Reference firmware: QTR-1A photoreflector -> ADC -> framed samples on USB serial.
//
// Frame layout (docs/serial-frame.md, protocol version 1), little-endian:
//   a5 5a | 0x10|n | seq u16 | t_us u32 | n x u16 counts | CRC-16/CCITT-FALSE u16
// The CRC covers the header byte through the last count.
//
// Wiring: QTR-1A OUT -> A0 (more modules: A1.., raise CHANNELS), VIN -> 5 V, GND -> GND.
// Boards: any Arduino-compatible; on an Uno/Nano (UART bridge) 1 000 000 baud is exact
// at 16 MHz; on native-USB boards (Leonardo, RP2040, Teensy) the baud rate is ignored.
//
// Sampling never waits for the host: a frame that does not fit in the transmit buffer
// is dropped, and the host sees the gap in the sequence number.

#include <Arduino.h>

static const uint8_t CHANNELS = 1;               // 1..8
static const uint8_t PINS[CHANNELS] = {A0};
static const uint32_t PERIOD_US = 1000;           // 1 kHz
static const uint32_t BAUD = 1000000;
static const uint8_t VERSION = 1;
static const uint8_t FRAME_SIZE = 11 + 2 * CHANNELS;

static uint16_t seq = 0;
static uint32_t next_us = 0;

// CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor.
static uint16_t crc16(const uint8_t *data, uint8_t len) {
  uint16_t crc = 0xFFFF;
  while (len--) {
    crc ^= (uint16_t)(*data++) << 8;
    for (uint8_t bit = 0; bit < 8; bit++) {
      crc = (crc & 0x8000) ? (uint16_t)((crc << 1) ^ 0x1021) : (uint16_t)(crc << 1);
    }
  }
  return crc;
}

static void put16(uint8_t *p, uint16_t v) { p[0] = v & 0xFF; p[1] = v >> 8; }

static void put32(uint8_t *p, uint32_t v) {
  p[0] = v & 0xFF; p[1] = (v >> 8) & 0xFF; p[2] = (v >> 16) & 0xFF; p[3] = v >> 24;
}

void setup() {
  Serial.begin(BAUD);
#if defined(analogReadResolution)
  analogReadResolution(12);                        // SAMD/RP2040/Teensy: 12-bit codes
#endif
  next_us = micros();
}

void loop() {
  // Wait for the next period (wrap-safe unsigned arithmetic).
  if ((int32_t)(micros() - next_us) < 0) return;
  next_us += PERIOD_US;

  uint8_t frame[FRAME_SIZE];
  const uint32_t t_us = micros();                 // stamp at the conversion
  frame[0] = 0xA5;
  frame[1] = 0x5A;
  frame[2] = (uint8_t)((VERSION << 4) | CHANNELS);
  put16(frame + 3, seq);
  put32(frame + 5, t_us);
  for (uint8_t ch = 0; ch < CHANNELS; ch++) {
    put16(frame + 9 + 2 * ch, (uint16_t)analogRead(PINS[ch]));
  }
  put16(frame + 9 + 2 * CHANNELS, crc16(frame + 2, 7 + 2 * CHANNELS));

  // Drop rather than block when the host is not reading fast enough.
  if (Serial.availableForWrite() >= FRAME_SIZE) {
    Serial.write(frame, FRAME_SIZE);
  }
  seq++;                                          // counts sampled frames, sent or not
}
