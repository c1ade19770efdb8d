// Reference firmware: QTR-1A photoreflectors -> ADC -> framed samples on USB serial.
//
// Protocol version 2 (docs/serial-frame.md), little-endian, CRC-16/CCITT-FALSE over
// everything after the sync bytes:
//   data frame: a5 5a | 0x20|n | seq u16 | t_us u32 | n x u16 counts | crc u16
//   info frame: a5 5a | 0x20 | len u8 | adc_bits u8 | channels u8 | vref_mv u16 |
//               period_us u32 | name_len u8 | board name | crc u16
// The info frame says what the codes mean, so the host never has to be told: it is sent
// at start and every INFO_PERIOD_US.
//
// Modulated modules (-DTACTILE_MODULATED=1): protocol version 3. The emitters are switched
// apart from the detectors' pull-ups, from TACTILE_EMITTER_PINS digital pins starting at
// TACTILE_EMITTER_PIN (default: one pin, pin 2, driving every module's emitter: a QTR-MD/HD
// CTRL line, or a transistor feeding the QTR-1A LEDs). Each period has an emitter-on half
// and an emitter-off half; each half is sampled SETTLE_US after the switch, and the frame
// carries both:
//   data frame: a5 5a | 0x30|n | seq u16 | t_us u32 | n x u16 on | n x u16 off | crc u16
//   info frame: a5 5a | 0x30 | len u8 | (version 2's fields) | modulation u8 = 1 |
//               settle_us u16 | read_us u16 | crc u16
// A build without TACTILE_MODULATED speaks version 2, byte for byte as before.
//
// Wiring: QTR-1A OUT -> A0 (more modules: A1.., raise CHANNELS), VIN -> the board's ADC
// reference (5 V on an Uno, 3.3 V on 3.3 V boards), GND -> GND. Channel c is pin A0 + c.
// Eight modules need eight analog inputs: the Nano (ATmega328P in TQFP, A0-A7); the Uno's
// DIP package has A0-A5 only, and a count above the board's inputs does not compile.
// Boards: the resolution, reference and name come from the boards' own macros below; on an
// Uno/Nano (UART bridge) 1 000 000 baud is exact at 16 MHz; on native-USB boards
// (Leonardo, SAMD, RP2040, Teensy) the baud rate is ignored.
//
// Sampling never waits for the host: a frame that does not fit in the transmit buffer
// is dropped, and the host sees the gap in the sequence number.

#include <Arduino.h>

#ifndef TACTILE_CHANNELS
#define TACTILE_CHANNELS 1
#endif
#ifndef TACTILE_MODULATED
#define TACTILE_MODULATED 0
#endif

// What this board's ADC gives. Another board: define all three when compiling, e.g.
// -DTACTILE_ADC_BITS=12 -DTACTILE_VREF_MV=3300 -DTACTILE_BOARD='"esp32"', and make
// setup() switch the ADC to that resolution.
#if defined(TACTILE_ADC_BITS)
#elif defined(ARDUINO_ARCH_AVR)       // Uno, Nano, Mega, Leonardo: 10-bit ADC, AVcc reference
#define TACTILE_ADC_BITS 10
#define TACTILE_BOARD "avr"
#elif defined(ARDUINO_ARCH_RENESAS)   // Uno R4: 5 V like the Uno, 12 bit on request
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "renesas"
#elif defined(ARDUINO_ARCH_SAMD)      // Zero, MKR, Nano 33 IoT: 3.3 V
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "samd"
#elif defined(ARDUINO_ARCH_SAM)       // Due: 3.3 V
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "sam"
#elif defined(ARDUINO_ARCH_RP2040)    // Raspberry Pi Pico (arduino-pico, mbed): 3.3 V
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "rp2040"
#elif defined(TEENSYDUINO)            // Teensy 3.x/4.x: 3.3 V
#define TACTILE_ADC_BITS 12
#define TACTILE_BOARD "teensy"
#else
#error "Unknown board: define TACTILE_ADC_BITS, TACTILE_VREF_MV and TACTILE_BOARD."
#endif

#ifndef TACTILE_BOARD
#define TACTILE_BOARD "custom"
#endif
#ifndef TACTILE_VREF_MV
#if defined(ARDUINO_ARCH_AVR) || defined(ARDUINO_ARCH_RENESAS)
#define TACTILE_VREF_MV 5000          // a 3.3 V AVR board (Pro Mini 8 MHz): -DTACTILE_VREF_MV=3300
#else
#define TACTILE_VREF_MV 3300
#endif
#endif

static const uint8_t CHANNELS = TACTILE_CHANNELS;  // 1..8, pins A0..A(CHANNELS-1)
static const bool MODULATED = TACTILE_MODULATED != 0;
// 1 kHz; modulated 500 Hz: the detector's response bounds the switching (see SETTLE_US)
static const uint32_t PERIOD_US = MODULATED ? 2000 : 1000;
static const uint32_t INFO_PERIOD_US = 250000;      // info frame 4x per second
static const uint32_t BAUD = 1000000;
static const uint8_t VERSION = MODULATED ? 3 : 2;
static const uint8_t SAMPLES = MODULATED ? 2 * CHANNELS : CHANNELS;  // codes per frame
static const uint8_t FRAME_SIZE = 11 + 2 * SAMPLES;
static const char BOARD[] = TACTILE_BOARD;
static const uint8_t NAME_LEN = sizeof(BOARD) - 1;
static const uint8_t MODULATION_FIELDS = MODULATED ? 5 : 0;  // modulation, settle_us, read_us
static const uint8_t INFO_PAYLOAD = 9 + NAME_LEN + MODULATION_FIELDS;
static const uint8_t INFO_SIZE = 4 + INFO_PAYLOAD + 2;

static_assert(CHANNELS >= 1 && CHANNELS <= 8, "CHANNELS must be 1..8");
#if defined(NUM_ANALOG_INPUTS)                    // the board's variant says how many pins
static_assert(CHANNELS <= NUM_ANALOG_INPUTS,
              "TACTILE_CHANNELS exceeds this board's analog inputs (NUM_ANALOG_INPUTS); "
              "8 channels need a board with A0-A7 such as the Nano, not the Uno");
#endif

#if defined(ARDUINO_ARCH_AVR) && defined(ADCSRA)
// ADC clock on AVR. The core starts the ADC at F_CPU / 128 (125 kHz at 16 MHz); a
// conversion is 13 ADC clocks (ATmega328P datasheet, "Analog-to-Digital Converter"), about
// 112 us per analogRead with its overhead, so 8 channels would take ~0.9 ms of the 1 ms
// period and leave too little for the CRC and the serial frame. The datasheet asks for a
// 50-200 kHz ADC clock for full 10-bit resolution and allows a faster clock for lower
// resolution (its typical absolute accuracy: 2 LSB at 200 kHz, 4.5 LSB at 1 MHz). So when
// the conversions would take over half the period, the sketch uses F_CPU / 32 (500 kHz,
// ~28 us a read) and accepts the slightly reduced accuracy. Prescaler bits ADPS2:0 in
// ADCSRA: 0b111 = 128, 0b101 = 32. -DTACTILE_ADC_PRESCALER=128 keeps the slow clock.
#ifndef TACTILE_ADC_PRESCALER
#define TACTILE_ADC_PRESCALER (TACTILE_CHANNELS * 112 > 500 ? 32 : 128)
#endif
static_assert(TACTILE_ADC_PRESCALER == 32 || TACTILE_ADC_PRESCALER == 128,
              "TACTILE_ADC_PRESCALER must be 32 or 128");
static const uint8_t ADPS_MASK = (1 << ADPS2) | (1 << ADPS1) | (1 << ADPS0);
static const uint8_t ADPS_BITS =
    TACTILE_ADC_PRESCALER == 32 ? (uint8_t)((1 << ADPS2) | (1 << ADPS0)) : ADPS_MASK;
#endif
static_assert(TACTILE_ADC_BITS >= 1 && TACTILE_ADC_BITS <= 16, "ADC bits must be 1..16");
static_assert(NAME_LEN <= 31, "the board name has at most 31 characters");

// Emitter switching (modulated builds). The QRE1113 on the QTR-1A's 47 kOhm pull-up
// settles with a time constant tau = 0.43 ms (docs/ambient.md: the datasheet's 20 us rise
// at 1 kOhm scaled to the load; physics/detector.py). A sample SETTLE_US after a switch
// still misses exp(-SETTLE_US / tau) of the change, so each half period waits as long as
// it can: half the period less the conversions (READ_US each) and a margin for the frame.
// At 500 Hz that is 0.79 ms (1.8 tau) for one channel on an AVR; the on - off difference
// keeps 71 % of the emitter's light (docs/firmware.md), which the driver scales back. A
// full settle (5 tau) would need a 4.5 ms period and leave the two samples 2.2 ms apart,
// where a lamp's 100 Hz flicker no longer cancels in the difference.
#ifndef TACTILE_EMITTER_PIN
#define TACTILE_EMITTER_PIN 2          // 0 and 1 are the serial port on UART boards
#endif
#ifndef TACTILE_EMITTER_PINS
#define TACTILE_EMITTER_PINS 1         // one line switches every module's emitter
#endif
#if defined(ARDUINO_ARCH_AVR) && defined(ADCSRA)
static const uint16_t READ_US = TACTILE_ADC_PRESCALER == 32 ? 28 : 112;  // per analogRead
#else
static const uint16_t READ_US = 10;
#endif
static const uint16_t FRAME_MARGIN_US = 100;        // the frame's CRC and bookkeeping
static const uint16_t SETTLE_US =
    (uint16_t)(PERIOD_US / 2 - CHANNELS * READ_US - FRAME_MARGIN_US);
static_assert(!MODULATED || CHANNELS * READ_US + FRAME_MARGIN_US + 200 <= PERIOD_US / 2,
              "TACTILE_MODULATED: the conversions leave under 0.2 ms to settle in each half "
              "period; use fewer channels or the fast ADC clock (TACTILE_ADC_PRESCALER=32)");
static_assert(!MODULATED || (TACTILE_EMITTER_PINS >= 1 && TACTILE_EMITTER_PIN >= 2 &&
                             TACTILE_EMITTER_PIN + TACTILE_EMITTER_PINS <= A0),
              "TACTILE_MODULATED: this board has too few pins for TACTILE_CHANNELS analog "
              "inputs plus TACTILE_EMITTER_PINS emitter pins (digital pins from "
              "TACTILE_EMITTER_PIN up to A0); switch every emitter from one pin or use a "
              "board with more pins");

static uint16_t seq = 0;
static uint32_t next_us = 0;
static uint32_t next_info_us = 0;

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

// Send the info frame if it fits now; false means try again on the next loop.
static bool send_info() {
  if (Serial.availableForWrite() < INFO_SIZE) return false;
  uint8_t frame[INFO_SIZE];
  frame[0] = 0xA5;
  frame[1] = 0x5A;
  frame[2] = (uint8_t)(VERSION << 4);              // channel count 0: info frame
  frame[3] = INFO_PAYLOAD;
  frame[4] = TACTILE_ADC_BITS;
  frame[5] = CHANNELS;
  put16(frame + 6, TACTILE_VREF_MV);
  put32(frame + 8, PERIOD_US);
  frame[12] = NAME_LEN;
  for (uint8_t i = 0; i < NAME_LEN; i++) frame[13 + i] = (uint8_t)BOARD[i];
  if (MODULATED) {                                // after the name: version 3's fields
    frame[13 + NAME_LEN] = 1;                     // modulation: on/off pairs
    put16(frame + 14 + NAME_LEN, SETTLE_US);
    put16(frame + 16 + NAME_LEN, READ_US);
  }
  put16(frame + 4 + INFO_PAYLOAD, crc16(frame + 2, 2 + INFO_PAYLOAD));
  Serial.write(frame, INFO_SIZE);
  return true;
}

void setup() {
  Serial.begin(BAUD);
#if TACTILE_ADC_BITS != 10
  analogReadResolution(TACTILE_ADC_BITS);         // every core above starts at 10 bit
#endif
#if defined(ARDUINO_ARCH_AVR) && defined(ADCSRA)
  ADCSRA = (uint8_t)((ADCSRA & ~ADPS_MASK) | ADPS_BITS);
#endif
  if (MODULATED) {
    for (uint8_t p = 0; p < TACTILE_EMITTER_PINS; p++) {
      pinMode(TACTILE_EMITTER_PIN + p, OUTPUT);
      digitalWrite(TACTILE_EMITTER_PIN + p, LOW);
    }
  }
  next_us = micros();
  next_info_us = next_us;
}

static void set_emitters(uint8_t level) {
  for (uint8_t p = 0; p < TACTILE_EMITTER_PINS; p++) digitalWrite(TACTILE_EMITTER_PIN + p, level);
}

static void wait_until(uint32_t t) {
  const int32_t left = (int32_t)(t - micros());
  if (left > 0) delayMicroseconds((unsigned int)left);
}

static uint8_t data[FRAME_SIZE];                  // the data frame being built
static bool pending = false;                      // a modulated frame waiting to be sent

// One modulated period from t0: the emitters on for the first half, off for the second,
// each half sampled SETTLE_US after its switch. The previous period's frame is sent while
// the detector settles, so the serial port never delays a switch.
static void modulated_period(uint32_t t0) {
  set_emitters(HIGH);
  if (pending && Serial.availableForWrite() >= FRAME_SIZE) Serial.write(data, FRAME_SIZE);
  pending = false;
  if ((int32_t)(t0 - next_info_us) >= 0 && send_info()) next_info_us = t0 + INFO_PERIOD_US;
  wait_until(t0 + SETTLE_US);
  const uint32_t t_us = micros();                 // the on sample's conversion
  for (uint8_t ch = 0; ch < CHANNELS; ch++) {
    put16(data + 9 + 2 * ch, (uint16_t)analogRead(A0 + ch));
  }
  wait_until(t0 + PERIOD_US / 2);
  set_emitters(LOW);
  wait_until(t0 + PERIOD_US / 2 + SETTLE_US);
  for (uint8_t ch = 0; ch < CHANNELS; ch++) {
    put16(data + 9 + 2 * (CHANNELS + ch), (uint16_t)analogRead(A0 + ch));
  }
  data[0] = 0xA5;
  data[1] = 0x5A;
  data[2] = (uint8_t)((VERSION << 4) | CHANNELS);
  put16(data + 3, seq);
  put32(data + 5, t_us);
  put16(data + 9 + 2 * SAMPLES, crc16(data + 2, 7 + 2 * SAMPLES));
  pending = true;
  seq++;                                          // counts sampled frames, sent or not
}

void loop() {
  const uint32_t now = micros();
  if (MODULATED) {
    if ((int32_t)(now - next_us) < 0) return;
    const uint32_t t0 = next_us;
    next_us += PERIOD_US;
    modulated_period(t0);
    return;
  }
  if ((int32_t)(now - next_info_us) >= 0 && send_info()) {
    next_info_us = now + INFO_PERIOD_US;
  }
  // Wait for the next period (wrap-safe unsigned arithmetic).
  if ((int32_t)(now - next_us) < 0) return;
  next_us += PERIOD_US;

  const uint32_t t_us = micros();                 // stamp at the conversion
  data[0] = 0xA5;
  data[1] = 0x5A;
  data[2] = (uint8_t)((VERSION << 4) | CHANNELS);
  put16(data + 3, seq);
  put32(data + 5, t_us);
  for (uint8_t ch = 0; ch < CHANNELS; ch++) {
    put16(data + 9 + 2 * ch, (uint16_t)analogRead(A0 + ch));
  }
  put16(data + 9 + 2 * CHANNELS, crc16(data + 2, 7 + 2 * CHANNELS));

  // Drop rather than block when the host is not reading fast enough.
  if (Serial.availableForWrite() >= FRAME_SIZE) {
    Serial.write(data, FRAME_SIZE);
  }
  seq++;                                          // counts sampled frames, sent or not
}
