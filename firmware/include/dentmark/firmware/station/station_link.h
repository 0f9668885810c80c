#pragma once
// The station on the host<->edge link (docs/protocol.md §8): what each request gets.
//   DefectList                  → Ack (stored and queued) or Error (refused)
//   Status (any content)        → the station's Status
//   MarkReport without records  → the job's outcomes so far, then on the same
//                                 connection each new outcome and a Status every
//                                 heartbeat until the job has ended (subscription)
//   anything else               → Error unsupported

#include "dentmark/common/clock/clock.h"
#include "dentmark/firmware/link/link_server.h"
#include "dentmark/firmware/station/station.h"

namespace dentmark::station {

link::Handler link_handler(Station& station, clock::Clock& clock);

}  // namespace dentmark::station
