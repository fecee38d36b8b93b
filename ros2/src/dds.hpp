#pragma once
// A thin layer over Cyclone DDS's C API for mobmap_ros2: a participant in one domain,
// readers that hand over each sample's CDR bytes as received (decoded by the same code
// as the bag readers), writers of the idlc-generated ROS 2 types, and a watch on the
// domain's publications (wrong types on our topics, peers coming and going).
#include <dds/dds.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace mobmap::ros2 {

/// DDS failed: the call and Cyclone's reason.
class DdsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Qos {
  bool reliable = false;
  bool transient_local = false;
  int depth = 5;
  /// ROS 2's names for the profile, for docs and warnings.
  [[nodiscard]] std::string describe() const;
};
/// ROS 2's profiles: sensor data (best effort, volatile, keep last 5); a latched map
/// (reliable, transient local, keep last 1); tf2's listeners (reliable, keep last 100).
Qos sensorQos();
Qos latchedQos();
Qos tfQos();
Qos tfStaticQos();
Qos serviceQos();

class Participant {
 public:
  /// Joins `domain_id` with Cyclone's configuration `config` (XML, or file URIs, as
  /// CYCLONEDDS_URI takes them; later entries win).
  Participant(std::uint32_t domain_id, const std::string& config);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;
  [[nodiscard]] dds_entity_t handle() const { return participant_; }
  /// The topic `name` of `type` (created once per name).
  dds_entity_t topic(const dds_topic_descriptor_t* type, const std::string& name);

 private:
  dds_entity_t domain_ = 0, participant_ = 0;
  std::vector<std::pair<std::string, dds_entity_t>> topics_;
};

/// A reader whose samples arrive as their CDR bytes (the 4-byte encapsulation header first).
class RawReader {
 public:
  using Handler = std::function<void(const RawReader& reader, const std::uint8_t* data, std::size_t size)>;
  RawReader(Participant& p, const dds_topic_descriptor_t* type, const std::string& topic, const Qos& qos, Handler handler);
  ~RawReader();
  RawReader(const RawReader&) = delete;
  RawReader& operator=(const RawReader&) = delete;
  /// Takes every waiting sample and hands it to the handler; returns how many.
  int takeAll();
  [[nodiscard]] dds_entity_t handle() const { return reader_; }
  [[nodiscard]] dds_entity_t condition() const { return condition_; }
  [[nodiscard]] const std::string& topic() const { return topic_; }
  [[nodiscard]] const std::string& typeName() const { return type_name_; }
  /// Samples DDS lost on the way (sample-lost status), writers matched now, and the
  /// writers whose QoS this reader could not match.
  [[nodiscard]] std::uint32_t lost() const;
  [[nodiscard]] std::int32_t matched() const;
  [[nodiscard]] std::uint32_t incompatible() const;

 private:
  dds_entity_t reader_ = 0, condition_ = 0;
  std::string topic_, type_name_;
  Handler handler_;
  std::vector<std::uint8_t> buffer_;
};

/// A writer of one idlc-generated type.
class Writer {
 public:
  Writer(Participant& p, const dds_topic_descriptor_t* type, const std::string& topic, const Qos& qos);
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;
  /// Writes a sample of the writer's type; DdsError when DDS refuses it.
  void write(const void* sample);
  /// Readers matched now.
  [[nodiscard]] std::int32_t matched() const;
  [[nodiscard]] const std::string& topic() const { return topic_; }

 private:
  dds_entity_t writer_ = 0;
  std::string topic_;
};

/// A publication seen in the domain (DCPSPublication).
struct Publication {
  std::string topic, type;
  bool alive = true;  ///< false: its writer or participant left
};

/// Watches the domain's publications.
class PublicationWatch {
 public:
  using Handler = std::function<void(const Publication&)>;
  PublicationWatch(Participant& p, Handler handler);
  ~PublicationWatch();
  int takeAll();
  [[nodiscard]] dds_entity_t condition() const { return condition_; }

 private:
  dds_entity_t reader_ = 0, condition_ = 0;
  Handler handler_;
};

/// Waits on readers' conditions and a guard that wake() triggers.
class WaitSet {
 public:
  explicit WaitSet(Participant& p);
  ~WaitSet();
  void attach(dds_entity_t condition);
  /// Waits up to `timeout_ms`; returns whether anything triggered.
  bool wait(int timeout_ms);
  void wake();

 private:
  dds_entity_t waitset_ = 0, guard_ = 0;
};

}  // namespace mobmap::ros2
