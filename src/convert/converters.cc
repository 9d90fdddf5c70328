#include "util/text.h"
#include "walkgraph/convert.h"

namespace walkgraph {

namespace {

Status OnlyIpinStarts(const std::string& format, const ConvertOptions& o) {
  if (o.known_start) {
    return InvalidArgument(format + ": the known-start option applies to ipin logs only");
  }
  return Status::Ok();
}

}  // namespace

const std::vector<ConverterInfo>& Converters() {
  static const std::vector<ConverterInfo> converters = {
      {"plaza", "DIR holding Plaza*_DR.txt, Plaza*_TD.txt, Plaza*_anchors.csv [, Plaza*_GT.csv]",
       [](const std::vector<std::string>& src, const ConvertOptions& o,
          std::vector<std::string>* warnings) -> StatusOr<Walk> {
         if (src.size() != 1) return InvalidArgument("plaza: expected one source directory");
         WG_RETURN_IF_ERROR(OnlyIpinStarts("plaza", o));
         return ConvertPlaza(src[0], o, warnings);
       }},
      {"pyshoe", "CSV of the PyShoe VICON set (t_s, acc, gyro, gt_x/y/z_m, zv_vicon)",
       [](const std::vector<std::string>& src, const ConvertOptions& o,
          std::vector<std::string>* warnings) -> StatusOr<Walk> {
         if (src.size() != 1) return InvalidArgument("pyshoe: expected one CSV file");
         WG_RETURN_IF_ERROR(OnlyIpinStarts("pyshoe", o));
         return ConvertPyshoe(src[0], o, warnings);
       }},
      {"ipin", "IPIN 2023 Track 3 GetSensorData LOG.txt [BLE_Locations.csv]",
       [](const std::vector<std::string>& src, const ConvertOptions& o,
          std::vector<std::string>* warnings) -> StatusOr<Walk> {
         if (src.empty() || src.size() > 2) {
           return InvalidArgument("ipin: expected LOG.txt [BLE_Locations.csv]");
         }
         return ConvertIpin(src[0], src.size() == 2 ? src[1] : std::string(), o, warnings);
       }},
      {"bletracks", "BLE RSSI track TRACK.mbd [tetam.dev] (Danis et al. 2022)",
       [](const std::vector<std::string>& src, const ConvertOptions& o,
          std::vector<std::string>* warnings) -> StatusOr<Walk> {
         if (src.empty() || src.size() > 2) {
           return InvalidArgument("bletracks: expected TRACK.mbd [tetam.dev]");
         }
         WG_RETURN_IF_ERROR(OnlyIpinStarts("bletracks", o));
         return ConvertBleTracks(src[0], src.size() == 2 ? src[1] : std::string(), o, warnings);
       }},
  };
  return converters;
}

StatusOr<Walk> Convert(const std::string& format, const std::vector<std::string>& sources,
                       const ConvertOptions& options, std::vector<std::string>* warnings) {
  std::string known;
  for (const ConverterInfo& c : Converters()) {
    if (c.format == format) return c.convert(sources, options, warnings);
    known += (known.empty() ? "" : ", ") + c.format;
  }
  return NotFound("unknown format " + internal::Quoted(format) + "; known: " + known);
}

}  // namespace walkgraph
