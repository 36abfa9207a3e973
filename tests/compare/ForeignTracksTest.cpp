// Tracks from trackpy and TrackMate read into the shared schema (ForeignTracks.hpp).
// The trackpy case uses trackpy's own linking of five real frames (its test data,
// ../shared/data/trackpy-tests: 100 features, 21 tracks with search range 5 px);
// the TrackMate files follow the layout of TrackMate 7's Spots-table CSV export
// (feature keys, then names, short names and units rows).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "../InputErrorMessage.hpp"
#include "../TestScratch.hpp"
#include "mmval/compare/ForeignTracks.hpp"
#include "mmval/core/Error.hpp"

namespace mmval::compare {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path write(const std::string& name, const std::string& text) {
  const fs::path p = test::scratch("foreign-tracks-" + name);
  std::ofstream(p) << text;
  return p;
}

std::vector<std::string> lines(const fs::path& p) {
  std::ifstream in(p);
  std::vector<std::string> out;
  std::string l;
  while (std::getline(in, l)) {
    if (!l.empty() && l.back() == '\r') l.pop_back();  // trackpy's files were written with CRLF line ends
    if (!l.empty()) out.push_back(l);
  }
  return out;
}

/// trackpy's linked output of its own test frames, saved as pandas' to_csv writes
/// it: an unnamed index column first, then y, x, frame (as floats), particle.
fs::path trackpyLinkedFile() {
  const fs::path ref = fs::path(MMVAL_SHARED_DATA_DIR) / "trackpy-tests" / "reference";
  const auto features = lines(ref / "link_input.csv"), ids = lines(ref / "link_sr5_mem0_ids.csv");
  EXPECT_EQ(features.front(), "y,x,frame");
  EXPECT_EQ(ids.front(), "particle");
  EXPECT_EQ(features.size(), ids.size());
  std::string text = ",y,x,frame,particle\n";
  for (std::size_t i = 1; i < features.size(); ++i) text += fmt::format("{},{},{}\n", i - 1, features[i], ids[i]);
  return write("trackpy.csv", text);
}

TEST(ForeignTracks, TrackpyLinkedDataFrameKeepsTrackpysTracks) {
  const fs::path f = trackpyLinkedFile();
  EXPECT_EQ(sniffTrackFormat(f), TrackFormat::trackpy);
  const ImportedTracks r = readTracksAnyFormat(f, {TrackFormat::automatic, 0.5e-6, 20.0});
  EXPECT_EQ(r.format, TrackFormat::trackpy);
  ASSERT_EQ(r.tracks.points.size(), 100u);  // the 100 features of link_input.csv (PROVENANCE.md)
  std::set<std::int64_t> tracks;
  for (const auto& p : r.tracks.points) tracks.insert(p.particle);
  EXPECT_EQ(tracks.size(), 21u);  // trackpy's 21 tracks at search range 5 px, memory 0
  // Sorted by particle then frame; time = frame / fps; micrometres = pixels x pixel size.
  for (std::size_t i = 1; i < r.tracks.points.size(); ++i) {
    const auto &a = r.tracks.points[i - 1], &b = r.tracks.points[i];
    EXPECT_TRUE(a.particle < b.particle || (a.particle == b.particle && a.frame < b.frame)) << "row " << i;
  }
  for (const auto& p : r.tracks.points) {
    EXPECT_NEAR(p.t, p.frame / 20.0, 1e-12);
    EXPECT_NEAR(p.x, p.x_px * 0.5e-6, 1e-18);
    EXPECT_NEAR(p.y, p.y_px * 0.5e-6, 1e-18);
    EXPECT_GT(p.x_px, 280.0);  // the crop of link_input.csv: 280 < x < 320, y < 280
    EXPECT_LT(p.x_px, 320.0);
    EXPECT_LT(p.y_px, 280.0);
  }
  EXPECT_THAT(r.note, HasSubstr("20 Hz"));
}

TEST(ForeignTracks, TrackpyNeedsFrameRateAndPixelSizeAndLinking) {
  const fs::path f = trackpyLinkedFile();
  EXPECT_THAT(test::inputErrorMessage([&] { readTracksAnyFormat(f, {TrackFormat::trackpy, 0.5e-6, 0.0}); }), HasSubstr("--fps"));
  EXPECT_THAT(test::inputErrorMessage([&] { readTracksAnyFormat(f, {TrackFormat::trackpy, 0.0, 20.0}); }), HasSubstr("--pixel-size-um"));
  const fs::path unlinked = write("unlinked.csv", ",y,x,mass,frame\n0,1.5,2.5,100,0\n");
  EXPECT_THAT(test::inputErrorMessage([&] { readTracksAnyFormat(unlinked, {TrackFormat::automatic, 1e-6, 10.0}); }), HasSubstr("trackpy.link"));
  const fs::path bad = write("bad-x.csv", "y,x,frame,particle\n1.5,abc,0,1\n");
  const std::string msg = test::inputErrorMessage([&] { readTracksAnyFormat(bad, {TrackFormat::trackpy, 1e-6, 10.0}); });
  EXPECT_THAT(msg, HasSubstr(":2"));  // line 2
  EXPECT_THAT(msg, HasSubstr("abc"));
}

/// A TrackMate 7 Spots table: keys, names, short names, units; then spots.
std::string trackmateTable(const std::string& x_unit, const std::string& t_unit, const std::string& rows) {
  return "LABEL,ID,TRACK_ID,QUALITY,POSITION_X,POSITION_Y,POSITION_Z,POSITION_T,FRAME,RADIUS\n"
         "Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame,Radius\n"
         "Label,Spot ID,Track ID,Quality,X,Y,Z,T,Frame,R\n"
         ",,,(quality)," + x_unit + "," + x_unit + "," + x_unit + "," + t_unit + ",," + x_unit + "\n" + rows;
}

TEST(ForeignTracks, TrackmateSpotsInMicronsAndSeconds) {
  // Two tracks, one spot outside any track (empty TRACK_ID), rows out of order.
  const std::string rows =
      "ID1,1,0,12.5,10.0,20.0,0,0.5,1,1.2\n"
      "ID0,0,0,12.5,9.0,20.5,0,0.0,0,1.2\n"
      "ID7,7,,3.0,50.0,50.0,0,0.0,0,1.2\n"
      "ID2,2,3,10.0,30.0,5.0,0,0.0,0,1.2\n"
      "ID3,3,3,10.0,31.0,6.0,0,0.5,1,1.2\n";
  const fs::path f = write("trackmate-um.csv", trackmateTable("(micron)", "(sec)", rows));
  EXPECT_EQ(sniffTrackFormat(f), TrackFormat::trackmate);
  const ImportedTracks r = readTracksAnyFormat(f, {});
  ASSERT_EQ(r.tracks.points.size(), 4u);
  EXPECT_EQ(r.skipped_spots, 1);
  const auto& p0 = r.tracks.points[0];
  EXPECT_EQ(p0.particle, 0);
  EXPECT_EQ(p0.frame, 0);
  EXPECT_NEAR(p0.x, 9.0e-6, 1e-15);
  EXPECT_NEAR(p0.y, 20.5e-6, 1e-15);
  EXPECT_NEAR(r.tracks.points[1].t, 0.5, 1e-12);
  EXPECT_EQ(r.tracks.points[2].particle, 3);
  EXPECT_TRUE(std::isnan(p0.x_px));  // no pixel size given: no pixel columns
}

TEST(ForeignTracks, TrackmateInPixelsNeedsPixelSizeAndBranchedTracksAreLeftOut) {
  const std::string rows =
      "ID0,0,5,1,10,20,0,0,0,2\n"
      "ID1,1,5,1,11,20,0,1,1,2\n"
      "ID2,2,6,1,40,40,0,0,0,2\n"
      "ID3,3,6,1,41,40,0,1,1,2\n"
      "ID4,4,6,1,41,45,0,1,1,2\n";  // track 6 splits in frame 1
  const fs::path f = write("trackmate-px.csv", trackmateTable("(pixel)", "(frame)", rows));
  EXPECT_THAT(test::inputErrorMessage([&] { readTracksAnyFormat(f, {TrackFormat::automatic, 0.0, 10.0}); }), HasSubstr("pixel size"));
  EXPECT_THAT(test::inputErrorMessage([&] { readTracksAnyFormat(f, {TrackFormat::automatic, 2e-6, 0.0}); }), HasSubstr("--fps"));
  const ImportedTracks r = readTracksAnyFormat(f, {TrackFormat::automatic, 2e-6, 10.0});
  ASSERT_EQ(r.tracks.points.size(), 2u);
  EXPECT_EQ(r.skipped_tracks, 1);
  EXPECT_EQ(r.skipped_spots, 3);
  EXPECT_NEAR(r.tracks.points[1].x, 22e-6, 1e-15);
  EXPECT_NEAR(r.tracks.points[1].x_px, 11.0, 1e-9);
  EXPECT_NEAR(r.tracks.points[1].t, 0.1, 1e-12);
  const fs::path odd = write("trackmate-odd.csv", trackmateTable("(furlong)", "(sec)", "ID0,0,5,1,10,20,0,0,0,2\n"));
  EXPECT_THAT(test::inputErrorMessage([&] { readTracksAnyFormat(odd, {}); }), HasSubstr("furlong"));
}

TEST(ForeignTracks, UnknownHeaderIsNamed) {
  const fs::path f = write("unknown.csv", "a,b,c\n1,2,3\n");
  const std::string msg = test::inputErrorMessage([&] { readTracksAnyFormat(f, {}); });
  EXPECT_THAT(msg, HasSubstr("a,b,c"));
  EXPECT_THAT(msg, HasSubstr("TrackMate"));
  EXPECT_THROW(parseTrackFormat("csv"), std::invalid_argument);
}

TEST(ForeignTracks, MmvalFilesReadAsBefore) {
  const fs::path f = write("mmval.csv", "frame,particle,x,y,x_um,y_um,t_s\n0,1,10,20,5,10,0\n1,1,11,20,5.5,10,0.1\n");
  const ImportedTracks r = readTracksAnyFormat(f, {});
  EXPECT_EQ(r.format, TrackFormat::mmval);
  ASSERT_EQ(r.tracks.points.size(), 2u);
  EXPECT_NEAR(r.tracks.points[1].x, 5.5e-6, 1e-15);
}

}  // namespace
}  // namespace mmval::compare
