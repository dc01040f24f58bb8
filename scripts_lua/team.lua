-- Teams: one robot, then teams of 2 and 4 robots (burgard coordinator) from the same start on the dense
-- office; prints coverage, time to 95 % and paths, and saves the last team's map.
-- Run:  robotexp run scripts_lua/team.lua --out out
-- Units are IfTEA's: mm, mm/s, ms, degrees. Relative paths are relative to the output folder.

exploration.setWorld("dense")
exploration.setMethod(ExplorationMethod.FRONTIER)
robot.setMaxLaserRange(3000)
robot.setMaxSpeed(300)
exploration.setMaxTime(600000)            -- 10 min of robot time per run

local function t95(r)
  return r.time_to_coverage_95_s and string.format("%4.0f s", r.time_to_coverage_95_s) or "   - "
end

robot.moveMobileSim(-5000, 7500, 0)       -- the thesis's first start pose
exploration.start()
exploration.wait()
local one = exploration.results()
print(string.format("1 robot:  coverage %5.1f %%, 95 %% at %s, path %6.1f m", one.coverage * 100, t95(one),
                    one.path_length_m))

team.setCoordinator("burgard")            -- none, greedy, burgard, minpos
for _, n in ipairs({2, 4}) do
  robot.moveMobileSim(-5000, 7500, 0)     -- robot 1 starts there, the others beside it
  team.setRobots(n)                       -- n robots of robot.setModel's preset (p3dx)
  local r = team.explore()
  print(string.format("%d robots: coverage %5.1f %%, 95 %% at %s, total path %6.1f m, overlap %4.1f %%", n,
                      r.coverage * 100, t95(r), r.total_path_m, (r.overlap_ratio or 0) * 100))
  for i = 1, r.team_size do
    local x, y = team.getPose(i)
    print(string.format("  robot %d (%s): path %5.1f m over %d points, ends at (%.0f, %.0f) mm", i,
                        r.robots[i].robot, r.robots[i].path_length_m, #team.getPath(i), x, y))
  end
end

mapView.setMapScaling(0.05)               -- 50 px per metre
mapView.saveMapImage("team.png")          -- the last team's map, every robot's path
print("map image:    team.png in the output folder")
