#include "epiloc/io/result.h"

#include <gtest/gtest.h>

#include "eval/eval_test_util.h"

namespace epiloc {
namespace {

const std::string kHeader = "frame,timestamp_s,lat_deg,lon_deg,alt_m,s_m,db_frame,method,status";

TEST(ResultCsv, ReadsRowsStatusesAndExtraColumns) {
  TempDir dir;
  WriteText(dir / "r.csv",
            "# localizer output\n"
            "method,frame,status,timestamp_s,lat_deg,lon_deg,alt_m,s_m,db_frame,quality,"
            "heading_deg,qw,qx,qy,qz\n"
            "pnp,3,ok,10.5,49.0001,8.4002,101.25,12.5,7,0.9,\"1,5\",1,0,0,0\n"
            "gps,3,ok,10.5,49.0002,8.4001,100,,,,,,,,\n"
            "dtw_fixed,4,lost,10.6,,,,,,0.1,,,,,\n"
            "pnp,,rejected,10.7,49.1,8.4,100,,,,,,,,\n");
  const ResultTable table = ReadResultCsv(dir / "r.csv");
  ASSERT_EQ(table.rows.size(), 4u);
  EXPECT_EQ(table.extra_columns, (std::vector<std::string>{"quality", "heading_deg"}));
  const ResultRow& a = table.rows[0];
  EXPECT_EQ(a.method, "pnp");
  EXPECT_EQ(a.frame, 3);
  EXPECT_EQ(a.status, ResultStatus::kOk);
  EXPECT_EQ(a.timestamp_s, 10.5);
  EXPECT_TRUE(a.has_position);
  EXPECT_EQ(a.position.lat_deg, 49.0001);
  EXPECT_EQ(a.position.alt_m, 101.25);
  EXPECT_TRUE(a.has_s);
  EXPECT_EQ(a.s_m, 12.5);
  EXPECT_EQ(a.db_frame, 7);
  ASSERT_TRUE(a.enu_from_cam.has_value());
  EXPECT_EQ(a.extra, (std::vector<std::string>{"0.9", "1,5"}));
  EXPECT_EQ(a.line, 3);
  EXPECT_FALSE(table.rows[1].has_s);
  EXPECT_EQ(table.rows[1].db_frame, kInvalidImage);
  EXPECT_FALSE(table.rows[1].enu_from_cam.has_value());
  EXPECT_EQ(table.rows[2].status, ResultStatus::kLost);
  EXPECT_FALSE(table.rows[2].has_position);
  EXPECT_EQ(table.rows[3].frame, kInvalidFrame);
  EXPECT_EQ(table.rows[3].status, ResultStatus::kRejected);
  EXPECT_TRUE(table.rows[3].has_position);
  // Methods in KnownMethods() order, not file order.
  EXPECT_EQ(table.Methods(), (std::vector<std::string>{"gps", "dtw_fixed", "pnp"}));
}

TEST(ResultCsv, WriteThenReadGivesTheSameRows) {
  TempDir dir;
  ResultTable table;
  table.extra_columns = {"quality"};
  ResultRow row = OkRow("fit_free", 12, 1317042272.351950336, Eigen::Vector3d(1.0 / 3, 2, 0.5));
  row.has_s = true;
  row.s_m = 0.1 + 0.2;
  row.db_frame = 42;
  row.enu_from_cam =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  row.extra = {"good, very"};
  table.rows.push_back(row);
  ResultRow lost = StatusRow("vo", kInvalidFrame, 3.25, ResultStatus::kOffRoute);
  lost.extra = {""};
  table.rows.push_back(lost);
  WriteResultCsv(table, dir / "out.csv");
  const ResultTable back = ReadResultCsv(dir / "out.csv");
  ASSERT_EQ(back.rows.size(), 2u);
  EXPECT_EQ(back.extra_columns, table.extra_columns);
  const ResultRow& r = back.rows[0];
  EXPECT_EQ(r.frame, 12);
  EXPECT_EQ(r.timestamp_s, row.timestamp_s);
  EXPECT_EQ(r.position.lat_deg, row.position.lat_deg);
  EXPECT_EQ(r.position.lon_deg, row.position.lon_deg);
  EXPECT_EQ(r.position.alt_m, row.position.alt_m);
  EXPECT_EQ(r.s_m, row.s_m);
  EXPECT_EQ(r.db_frame, 42);
  ASSERT_TRUE(r.enu_from_cam.has_value());
  EXPECT_LT((r.enu_from_cam->coeffs() - row.enu_from_cam->coeffs()).norm(), 1e-15);
  EXPECT_EQ(r.extra, row.extra);
  EXPECT_EQ(back.rows[1].status, ResultStatus::kOffRoute);
  EXPECT_EQ(back.rows[1].frame, kInvalidFrame);
  EXPECT_FALSE(back.rows[1].enu_from_cam.has_value());
}

TEST(ResultCsv, StatusAndMethodNames) {
  EXPECT_EQ(StatusNames(),
            (std::vector<std::string>{"ok", "lost", "off_route", "rejected", "skipped"}));
  EXPECT_EQ(ParseStatus("skipped", "x"), ResultStatus::kSkipped);
  EXPECT_EQ(StatusName(ResultStatus::kOffRoute), "off_route");
  EXPECT_TRUE(IsKnownMethod("piecewise"));
  EXPECT_FALSE(IsKnownMethod("GPS"));
  EXPECT_TRUE(IsKnownMethod("colmap"));
  EXPECT_EQ(KnownMethods().size(), 14u);
  EXPECT_EQ(MethodRank("gps"), 0u);
}

TEST(ResultCsv, AcceptsAnyMethodName) {
  TempDir dir;
  WriteText(dir / "other.csv", "frame,timestamp_s,lat_deg,lon_deg,alt_m,s_m,db_frame,method,status\n"
                               "1,0,49,8,0,,,ORB-SLAM3,ok\n1,0,49,8,0,,,gps,ok\n2,0.1,49,8,0,,,sift,lost\n");
  const ResultTable table = ReadResultCsv(dir / "other.csv");
  EXPECT_EQ(table.Methods(), (std::vector<std::string>{"gps", "ORB-SLAM3", "sift"}));
}

// Each bad file gives an error naming the file and line.
TEST(ResultCsv, RejectsBadInputNamingFileAndLine) {
  TempDir dir;
  const auto expect = [&](const std::string& name, const std::string& text,
                          const std::vector<std::string>& parts) {
    WriteText(dir / name, text);
    std::vector<std::string> all = parts;
    ExpectError([&] { ReadResultCsv(dir / name); }, all);
  };
  expect("missing.csv",
         "frame,timestamp_s,lat_deg,lon_deg,alt_m,s_m,db_frame,method\n1,2,3,4,5,,,gps\n",
         {dir / "missing.csv:1", "missing column 'status'"});
  expect("method.csv", kHeader + "\n1,0,49,8,0,,,gps,ok\n2,0.1,49,8,0,,,\"a b\",ok\n",
         {dir / "method.csv:3", "method name 'a b'"});
  expect("status.csv", kHeader + "\n1,0,49,8,0,,,gps,fine\n",
         {dir / "status.csv:2", "unknown status 'fine'", "ok, lost, off_route"});
  expect("nan.csv", kHeader + "\n1,0,nan,8,0,,,gps,ok\n", {dir / "nan.csv:2", "lat_deg"});
  expect("nan_time.csv", kHeader + "\n1,NaN,49,8,0,,,gps,ok\n", {dir / "nan_time.csv:2"});
  expect("no_position.csv", kHeader + "\n1,0,,,,,,pnp,ok\n",
         {dir / "no_position.csv:2", "status ok"});
  expect("partial.csv", kHeader + "\n1,0,49,,,,,pnp,lost\n", {dir / "partial.csv:2"});
  expect("range.csv", kHeader + "\n1,0,91,8,0,,,pnp,ok\n", {dir / "range.csv:2", "91"});
  expect("twice.csv", kHeader + "\n5,0,49,8,0,,,pnp,ok\n5,0.1,49,8,0,,,pnp,ok\n",
         {dir / "twice.csv:3", "frame 5 twice", "line 2"});
  expect("frame.csv", kHeader + "\nx,0,49,8,0,,,pnp,ok\n", {dir / "frame.csv:2", "frame"});
  expect("fields.csv", kHeader + "\n1,0,49,8,0,,,pnp\n", {dir / "fields.csv:2", "fields"});
  expect("empty.csv", kHeader + "\n", {dir / "empty.csv:2", "no rows"});
  expect("quat.csv", kHeader + ",qw,qx,qy,qz\n1,0,49,8,0,,,pnp,ok,2,0,0,0\n",
         {dir / "quat.csv:2", "norm"});
  expect("quat_cols.csv", kHeader + ",qw,qx\n1,0,49,8,0,,,pnp,ok,1,0\n",
         {dir / "quat_cols.csv:1", "qw,qx,qy,qz"});
  ExpectError([&] { ReadResultCsv(dir / "absent.csv"); }, {dir / "absent.csv"});
}

}  // namespace
}  // namespace epiloc
