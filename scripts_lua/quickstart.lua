-- Quick start: one exploration of the dense office world with the frontier explorer.
-- Run:  robotexp run scripts_lua/quickstart.lua --out out
-- Units are IfTEA's: mm, mm/s, ms, degrees. Relative paths are relative to the output folder.

robot.setAddress("sim")                   -- the embedded simulator
exploration.setWorld("dense")
robot.setMaxLaserRange(3000)
robot.setMaxSpeed(300)
exploration.setMethod(ExplorationMethod.FRONTIER)

robot.moveMobileSim(-5000, 7500, 0)       -- the thesis's first start pose
exploration.start()
exploration.wait()

local r = exploration.results()
print("elapsed time: " .. exploration.elapsedTime() .. " ms")
print("path length:  " .. robot.pathLength() .. " mm")
print(string.format("coverage:     %.1f %%  collisions: %d  (%s)", r.coverage * 100, r.collisions, r.reason))

mapView.setMapScaling(0.05)               -- 50 px per metre
robotView.setShowPath(true)
mapView.saveMapImage("quickstart.png")
print("map image:    quickstart.png in the output folder (--out, default out/)")
