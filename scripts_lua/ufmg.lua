-- The UFMG practical work's dynamic scene: a Kobuki follows each waypoint list with the potential-field
-- explorer while a person walks back and forth across the room; log-odds map of 5 cm cells, laser
-- noise uniform +-10 cm. The person must not remain in the maps.
-- Run:  robotexp run scripts_lua/ufmg.lua --out out/ufmg_lua
-- Units are IfTEA's: mm, mm/s, ms, degrees. Relative paths are relative to the output folder.

Paths = {
  {name = "path1", x = -4200, y = -4200, theta = 45},     -- from the lower-left corner
  {name = "path2", x = 4200, y = 4200, theta = -135},     -- from the upper-right corner
}

robot.setAddress("sim")
robot.setModel("kobuki")
exploration.setWorld("ufmg-dynamic")
robot.setMaxLaserRange(5000)
robot.setLaserNoise(100)                   -- uniform +-100 mm, as in the study
robot.setMaxSpeed(300)
exploration.setCellSize(50)                -- the study's choice among 10 / 50 / 100 mm
exploration.setMethod(ExplorationMethod.WAYPOINTS)

for _, p in ipairs(Paths) do
  exploration.setParameter("path", p.name) -- the world's goal list of that name
  robot.moveMobileSim(p.x, p.y, p.theta)
  exploration.start()
  exploration.wait()
  local r = exploration.results()
  print(string.format("%s: %s; path %.1f m in %.0f s, %d collisions", p.name, r.reason,
                      robot.pathLength() / 1000, exploration.elapsedTime() / 1000, r.collisions))
  mapView.setMapScaling(0.1)               -- 100 px per metre
  robotView.setShowPath(true)
  mapView.saveMapImage("ufmg_dynamic_" .. p.name .. ".png")
end
