// Converters from other people's recordings to the walk format.
//
// Each converter is strict like the readers: a malformed source line is reported as
// "file:line: what was expected". Whatever a converter had to repair in the source (reordered
// or duplicate lines) is counted in WalkMeta::extra under "convert.*", never silently.
#ifndef WALKGRAPH_CONVERT_H_
#define WALKGRAPH_CONVERT_H_

#include <functional>
#include <string>
#include <vector>

#include "walkgraph/status.h"
#include "walkgraph/walk.h"

namespace walkgraph {

// Options a converter may honour; one a format does not support is an error, not ignored.
struct ConvertOptions {
  // ipin: the walk starts at the first POSI landmark, whose position is given as a
  // position-only initial_pose (σ known_start_sigma_m; heading unknown), as the IPIN 2023
  // scoring trials provide it ("we provide the initial position", technical annex); the
  // recording before it is dropped (counted in "convert.*_before_start_dropped").
  bool known_start = false;
  double known_start_sigma_m = 0.5;  // not stated by IPIN: a walker standing at the marker
  // A physically impossible reading in the source (beyond the readers' ValidationLimits, io.h:
  // an RSSI of +42 dBm, an accelerometer spike past 300 m/s²) is dropped and counted in
  // meta.extra "convert.<stream>_invalid_dropped" (stream: imu, rss, range), with a warning
  // naming the source file:line of the first few; `strict` refuses the source instead.
  bool strict = false;
  // ipin: the WIFI lines too, each access point an anchor of unknown position (anchors.csv x, y
  // empty; group wifi; id kIpinWifiAnchorIdBase + the BSSID's last three bytes, the same in
  // every walk of a building), its readings in rss.csv; an access point heard fewer than
  // ipin_wifi_min_readings times is dropped (counted in "convert.wifi_*"): too few readings to
  // place it. Off by default: only the factor graphs place transmitters nobody surveyed.
  bool ipin_wifi = false;
  int ipin_wifi_min_readings = 10;
};
inline constexpr int kIpinWifiAnchorIdBase = 1000000000;

struct ConverterInfo {
  std::string format;       // "plaza", ...
  std::string description;  // what SRC... must be
  std::function<StatusOr<Walk>(const std::vector<std::string>& sources,
                               const ConvertOptions& options, std::vector<std::string>* warnings)>
      convert;
};

// Every converter shipped with the library.
const std::vector<ConverterInfo>& Converters();

// Runs the converter named `format` on `sources`. What it repaired or dropped is counted in
// meta.extra "convert.*"; `warnings` (when given) receives a line for each of the first dropped
// readings, "file:line: what was wrong; dropped".
StatusOr<Walk> Convert(const std::string& format, const std::vector<std::string>& sources,
                       const ConvertOptions& options = ConvertOptions(),
                       std::vector<std::string>* warnings = nullptr);

// Plaza1/Plaza2 (Djugash et al., CMU 2009; as shipped in GTSAM's examples/Data): `dir` holds
// <P>_DR.txt (t, Δdistance, Δheading), <P>_TD.txt (t, sender, anchor, range), <P>_anchors.csv
// and optionally <P>_GT.csv (t_s, x_m, y_m, heading_rad). The start pose is taken from the first
// ground-truth sample (as GTSAM's Plaza example does).
StatusOr<Walk> ConvertPlaza(const std::string& dir, const ConvertOptions& options = {},
                            std::vector<std::string>* warnings = nullptr);

// PyShoe VICON set (Wagstaff et al.; CSV with header t_s, ax/ay/az_mps2, gx/gy/gz_radps,
// gt_x/y/z_m, zv_vicon): a foot-mounted 200 Hz IMU → imu.csv, the Vicon foot position → truth
// (continuous, with z), zv_vicon → stance_truth. Time must increase; zv_vicon must be 0 or 1.
StatusOr<Walk> ConvertPyshoe(const std::string& csv_path, const ConvertOptions& options = {},
                             std::vector<std::string>* warnings = nullptr);
// IPIN 2023 Track 3 "GetSensorData" logfile (technical annex v2) + BLE_Locations.csv (bleID,
// Lat, Lon, floor; looked for beside the log when `ble_locations_csv` is empty) → a walk with
// a handheld IMU, BLE RSS to the beacons and POSI landmarks as checkpoint truth.
// - Frame: WGS84 latitude/longitude → east/north metres in the local tangent plane (ENU) at the
//   first POSI landmark of the log (origin kept in meta.extra "ipin.origin_lat_deg"/"_lon_deg").
// - IMU time base: the accelerometer samples. Each ACCE SensorTimestamp is mapped to the
//   app clock (the one of POSI and BLE4) by t = SensorTS + min_k(AppTS_k − SensorTS_k) over the
//   ACCE lines (the fastest delivery taken as zero latency); GYRO and MAGN, which share the
//   sensor clock, are linearly interpolated at each ACCE SensorTimestamp. ACCE samples outside
//   the GYRO (and MAGN) span are dropped (counted in "convert.imu_samples_outside_span").
// - RSS: BLE4 iBeacon lines, t = AppTimestamp, anchor id = the BLE number of BLE_Locations.csv
//   found for the iBeacon Minor by IpinMinorToBleId (see there: NOT Minor N = BLE N).
// - Floors: 2D positions; the POSI floor of each checkpoint is truth.csv's `floor`, the
//   floor of each beacon anchors.csv's `floor` (z_m 0: mounting height unknown); PRES lines
//   (t = AppTimestamp, hPa) → pressure.csv (a repeated AppTimestamp keeps the first reading).
//   The IPIN building's storey height is not published: walk.yaml keeps the default.
// - Start: see ConvertOptions::known_start (off: the whole log, no initial_pose).
StatusOr<Walk> ConvertIpin(const std::string& log_path, const std::string& ble_locations_csv,
                           const ConvertOptions& options = ConvertOptions(),
                           std::vector<std::string>* warnings = nullptr);

// The BLE id (row "BLEn" of BLE_Locations.csv) of the beacon broadcasting iBeacon Minor `minor`
// (MAC BE:AC:20:23:00:0<minor>), or -1 for a minor not deployed. Verified from the 2023
// training logs, not documented by the organisers (see src/convert/ipin.cc).
int IpinMinorToBleId(int minor);

// Position-annotated BLE RSSI tracks (Daniş et al., PMC 2022): `track_mbd` is a merged
// trk/*_all_sensors.mbd file (ts_unix, receiver MAC, beacon MAC, RSSI, x, y, z, 3×3 rotation),
// `devices_dev` the cnf/tetam.dev file (looked for at ../cnf/tetam.dev from the track when
// empty). The 12 fixed receivers become anchors with id = the number of their alias
// ("sensor10" → 10, ..., "sensor42" → 42); RSS is the receiver's reading of the carried beacon;
// the beacon's camera position on every line is continuous truth. No IMU. t = ts − ts of the
// first line (kept in meta.extra "bletracks.t0_unix_s").
StatusOr<Walk> ConvertBleTracks(const std::string& track_mbd, const std::string& devices_dev,
                                const ConvertOptions& options = {},
                                std::vector<std::string>* warnings = nullptr);

}  // namespace walkgraph

#endif  // WALKGRAPH_CONVERT_H_
