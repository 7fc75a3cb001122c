// continuum_imu: stream raw MPU9250 readings for `continuum-mhe live`.
//
// Board: Arduino UNO (ATmega328P, 16 MHz). Sensors: one or two MPU9250 (or
// MPU6500/9255) on one I2C bus, chosen at compile time with IMU_COUNT:
//   IMU_COUNT 1 (default): one sensor at MPU_ADDRESS (0x68, AD0 low; 0x69 for AD0 high)
//   IMU_COUNT 2: IMU 1 at 0x68 (AD0 to GND), IMU 2 at 0x69 (AD0 to 3.3 V); IMU 1 is the
//                first [[imu]] of the robot file (the one nearer the base)
// Plain Wire.h register access, no external library.
//
// Line protocol (ASCII, 115200 baud, one sample per line; a data line ends in '\n', a
// '#' line in "\r\n" as println ends it; the host takes LF, CR and CRLF alike):
//   t_ms,ax,ay,az,gx,gy,gz                      (one IMU)
//   t_ms,ax_1,ay_1,az_1,gx_1,gy_1,gz_1,ax_2,...  (two IMUs)
//     t_ms      device time, milliseconds since boot (millis())
//     ax,ay,az  specific force in m/s^2, sensor frame (flat and still: 0,0,+9.81)
//     gx,gy,gz  angular rate in rad/s, sensor frame, start-up bias removed
// Lines starting with '#' are comments: a banner with the version, ranges and rate
// at start-up, a '# fields: ...' line naming the fields, the gyro biases, and any
// error. The host shows them and counts them. A sensor that fails to answer costs the
// samples until it answers again (one '# error: I2C read failed' line each); it is then
// configured again, as is one found with other ranges than these (a power drop resets
// an MPU9250 to +-2 g and +-250 deg/s, which these scales would read twice too large).
//
// Mounting: put the sensor's z axis along the robot's tip tangent (pointing away
// from the base); see firmware/README.md and docs/hardware.md for other mountings
// (`--mount-rpy`) and calibration.

#include <Arduino.h>
#include <Wire.h>

#define FIRMWARE_VERSION "1.1.0"

#ifndef IMU_COUNT
#define IMU_COUNT 1
#endif
#if IMU_COUNT != 1 && IMU_COUNT != 2
#error "IMU_COUNT must be 1 or 2 (one I2C bus has two MPU9250 addresses)"
#endif
#ifndef RATE_HZ
#if IMU_COUNT == 1
#define RATE_HZ 100  // samples per second; up to about 200 at 115200 baud
#else
#define RATE_HZ 50  // a two-IMU line is ~100 bytes: 100 Hz would use ~90 % of 115200 baud
#endif
#endif
#ifndef BAUD
#define BAUD 115200
#endif
#ifndef MPU_ADDRESS
#define MPU_ADDRESS 0x68
#endif
#ifndef BIAS_SAMPLES
#define BIAS_SAMPLES 200  // gyro bias average at start-up (keep the robot still)
#endif

// MPU9250 registers
static const uint8_t REG_SMPLRT_DIV = 0x19;
static const uint8_t REG_CONFIG = 0x1A;
static const uint8_t REG_GYRO_CONFIG = 0x1B;
static const uint8_t REG_ACCEL_CONFIG = 0x1C;
static const uint8_t REG_ACCEL_CONFIG2 = 0x1D;  // follows REG_ACCEL_CONFIG
static const uint8_t REG_ACCEL_XOUT_H = 0x3B;
static const uint8_t REG_PWR_MGMT_1 = 0x6B;
static const uint8_t REG_WHO_AM_I = 0x75;

// Ranges: accelerometer +-4 g (8192 LSB/g), gyro +-500 deg/s (65.5 LSB/(deg/s)).
static const uint8_t ACCEL_FS_BITS = 1 << 3;
static const uint8_t GYRO_FS_BITS = 1 << 3;
static const float ACCEL_SCALE = 9.80665f / 8192.0f;              // m/s^2 per LSB
static const float GYRO_SCALE = (3.14159265f / 180.0f) / 65.5f;   // rad/s per LSB

static const unsigned long PERIOD_US = 1000000UL / RATE_HZ;

#if IMU_COUNT == 1
static const uint8_t ADDRESSES[IMU_COUNT] = {MPU_ADDRESS};
#else
static const uint8_t ADDRESSES[IMU_COUNT] = {0x68, 0x69};
#endif

static float gyro_bias[IMU_COUNT][3];
static bool configured[IMU_COUNT];  // false after a failed read: configure before the next
static unsigned long next_us = 0;
static unsigned int until_check = 0;  // samples until the ranges are read back

static bool writeRegister(uint8_t addr, uint8_t reg, uint8_t value) {
  Wire.beginTransmission(addr);
  Wire.write(reg);
  Wire.write(value);
  return Wire.endTransmission() == 0;
}

static bool readRegisters(uint8_t addr, uint8_t reg, uint8_t *buf, uint8_t count) {
  Wire.beginTransmission(addr);
  Wire.write(reg);
  if (Wire.endTransmission(false) != 0) return false;
  if (Wire.requestFrom(addr, count) != count) return false;
  for (uint8_t i = 0; i < count; i++) buf[i] = Wire.read();
  return true;
}

// Raw counts of one sensor: ax, ay, az, gx, gy, gz (temperature skipped).
static bool readRaw(uint8_t addr, int16_t out[6]) {
  uint8_t b[14];
  if (!readRegisters(addr, REG_ACCEL_XOUT_H, b, 14)) return false;
  for (uint8_t i = 0; i < 3; i++) {
    out[i] = (int16_t)(((uint16_t)b[2 * i] << 8) | b[2 * i + 1]);
    out[3 + i] = (int16_t)(((uint16_t)b[8 + 2 * i] << 8) | b[9 + 2 * i]);
  }
  return true;
}

// The sensor's clock, filters, rate and ranges; true where every write was taken.
static bool configure(uint8_t addr) {
  return writeRegister(addr, REG_PWR_MGMT_1, 0x01)         // clock: PLL from the gyro
         && writeRegister(addr, REG_CONFIG, 0x03)          // gyro DLPF 41 Hz, 1 kHz rate
         && writeRegister(addr, REG_SMPLRT_DIV, 0x00)      // 1 kHz updates; polled at RATE_HZ
         && writeRegister(addr, REG_GYRO_CONFIG, GYRO_FS_BITS)
         && writeRegister(addr, REG_ACCEL_CONFIG, ACCEL_FS_BITS)
         && writeRegister(addr, REG_ACCEL_CONFIG2, 0x03);  // accel DLPF 44.8 Hz
}

// Whether the sensor answers with the ranges the scales assume.
static bool rangesKept(uint8_t addr) {
  uint8_t fs[2];
  return readRegisters(addr, REG_GYRO_CONFIG, fs, 2) && (fs[0] & 0x18) == GYRO_FS_BITS &&
         (fs[1] & 0x18) == ACCEL_FS_BITS;
}

static uint8_t setupSensor(uint8_t addr) {
  writeRegister(addr, REG_PWR_MGMT_1, 0x80);  // reset
  delay(100);
  writeRegister(addr, REG_PWR_MGMT_1, 0x01);
  delay(10);
  uint8_t who = 0;
  if (!readRegisters(addr, REG_WHO_AM_I, &who, 1)) return 0;
  configure(addr);
  delay(50);
  return who;
}

// Wire's timeout where this core's Wire has one (AVR core 1.8.3 and later; some, such as
// Debian's, do not define WIRE_HAS_TIMEOUT): a stuck bus then fails a read instead of
// hanging the board.
template <typename W>
static auto setTimeout(W &wire, int) -> decltype(wire.setWireTimeout(3000UL, true), void()) {
  wire.setWireTimeout(3000UL, true);
}
template <typename W>
static void setTimeout(W &, long) {}

static bool isMpu(uint8_t who) { return who == 0x71 || who == 0x73 || who == 0x70; }

static void printField(const __FlashStringHelper *name, uint8_t imu) {
  Serial.print(',');
  Serial.print(name);
#if IMU_COUNT > 1
  Serial.print('_');
  Serial.print(imu + 1);
#else
  (void)imu;
#endif
}

// Every sensor's gyro bias, averaged over the same second (all sensors at once).
static void calibrateGyros() {
  long sum[IMU_COUNT][3] = {};
  int n[IMU_COUNT] = {};
  int16_t raw[6];
  for (int i = 0; i < BIAS_SAMPLES; i++) {
    for (uint8_t imu = 0; imu < IMU_COUNT; imu++) {
      if (readRaw(ADDRESSES[imu], raw)) {
        for (uint8_t k = 0; k < 3; k++) sum[imu][k] += raw[3 + k];
        n[imu]++;
      }
    }
    delay(5);
  }
  for (uint8_t imu = 0; imu < IMU_COUNT; imu++) {
    Serial.print(F("# gyro bias rad/s, IMU "));
    Serial.print(imu + 1);
    Serial.print(F(": "));
    for (uint8_t k = 0; k < 3; k++) {
      gyro_bias[imu][k] = n[imu] ? GYRO_SCALE * (float)sum[imu][k] / n[imu] : 0.0f;
      Serial.print(gyro_bias[imu][k], 5);
      if (k < 2) Serial.print(',');
    }
    Serial.println();  // "\r\n", as every '#' line ends
  }
}

static void printImu(uint8_t i) {
  Serial.print(F("IMU "));
  Serial.print(i + 1);
  Serial.print(F(" at 0x"));
  Serial.print(ADDRESSES[i], HEX);
}

void setup() {
  Serial.begin(BAUD);
  Wire.begin();
  Wire.setClock(400000);
  setTimeout(Wire, 0);
  uint8_t who[IMU_COUNT];
  for (uint8_t i = 0; i < IMU_COUNT; i++) {
    who[i] = setupSensor(ADDRESSES[i]);
    while (!isMpu(who[i])) {
      Serial.print(F("# error: no MPU9250 for IMU "));
      Serial.print(i + 1);
      Serial.print(F(" at I2C address 0x"));
      Serial.print(ADDRESSES[i], HEX);
      Serial.print(F(" (WHO_AM_I=0x"));
      Serial.print(who[i], HEX);
      Serial.println(F("); check wiring and AD0, retrying"));
      delay(1000);
      who[i] = setupSensor(ADDRESSES[i]);
    }
  }
  Serial.print(F("# continuum_imu " FIRMWARE_VERSION " mpu9250 imus="));
  Serial.print(IMU_COUNT);
  Serial.print(F(" who_am_i=0x"));
  Serial.print(who[0], HEX);
  Serial.print(F(" accel_range=+-4g gyro_range=+-500dps rate_hz="));
  Serial.print(RATE_HZ);
  Serial.print(F(" baud="));
  Serial.println(BAUD);
  Serial.print(F("# fields: t_ms"));
  for (uint8_t i = 0; i < IMU_COUNT; i++) {
    printField(F("ax"), i);
    printField(F("ay"), i);
    printField(F("az"), i);
    printField(F("gx"), i);
    printField(F("gy"), i);
    printField(F("gz"), i);
  }
  Serial.println(F(" (ms, m/s^2, rad/s; sensor frames)"));
  Serial.println(F("# calibrating gyro bias: keep the robot still"));
  calibrateGyros();
  for (uint8_t i = 0; i < IMU_COUNT; i++) configured[i] = true;
  next_us = micros();
}

void loop() {
  if ((long)(micros() - next_us) < 0) return;
  next_us += PERIOD_US;
  if ((long)(micros() - next_us) > (long)PERIOD_US) {  // fell behind: resynchronise
    next_us = micros() + PERIOD_US;
  }
  bool check = until_check == 0;  // the ranges, read back once a second
  until_check = check ? RATE_HZ : until_check - 1;
  for (uint8_t i = 0; i < IMU_COUNT; i++) {
    if (configured[i] && !(check && !rangesKept(ADDRESSES[i]))) continue;
    if (!configure(ADDRESSES[i]) || !rangesKept(ADDRESSES[i])) {
      configured[i] = false;  // still not answering: the read below says so
      continue;
    }
    Serial.print(F("# error: "));  // answering again (after a power drop?) or reset
    printImu(i);
    Serial.println(F(" configured again: its ranges were lost or it did not answer"));
    configured[i] = true;
  }
  int16_t raw[IMU_COUNT][6];
  unsigned long t = millis();
  for (uint8_t i = 0; i < IMU_COUNT; i++) {
    if (!configured[i] || !readRaw(ADDRESSES[i], raw[i])) {  // no sample at all
      configured[i] = false;
      Serial.print(F("# error: I2C read failed, "));
      printImu(i);
      Serial.println();
      return;
    }
  }
  Serial.print(t);
  for (uint8_t i = 0; i < IMU_COUNT; i++) {
    for (uint8_t k = 0; k < 3; k++) {
      Serial.print(',');
      Serial.print(ACCEL_SCALE * raw[i][k], 3);
    }
    for (uint8_t k = 0; k < 3; k++) {
      Serial.print(',');
      Serial.print(GYRO_SCALE * raw[i][3 + k] - gyro_bias[i][k], 4);
    }
  }
  Serial.print('\n');
}
