-- Santos 2016, Table 8, as a Lua script (the same runs as campaigns/santos.toml, one after another):
-- the firefly algorithm, the GA and the exhaustive optimum choose exploration targets on the
-- proportional-loss objective, five runs each (seeds 0-4) in the dense and the sparse world, mapped
-- at 5 cm cells. Each run appends its record to results.jsonl and saves its map; afterwards
--   robotexp campaign report OUT/results.jsonl     prints Table 8 with Welch's t-test.
-- Run:  robotexp run scripts_lua/santos.lua --out out/santos_lua      (about 20 min on one core)
--       SEEDS=1 in the line below for a quick look.
-- Units are IfTEA's: mm, mm/s, ms, degrees. Relative paths are relative to the output folder.

local SEEDS = 5
local Worlds = {                            -- each run starts at the world's pose "1"
  {name = "dense", x = -5000, y = 7500, theta = 0},
  {name = "sparse", x = -12000, y = -4000, theta = 0},
}
local Methods = {
  {key = ExplorationMethod.META_FIREFLY, label = "FA"},
  {key = ExplorationMethod.META_GA, label = "GA"},
  {key = ExplorationMethod.META_EXHAUSTIVE, label = "optimum"},
}

robot.setAddress("sim")
robot.setMaxLaserRange(3000)
robot.setMaxSpeed(300)
exploration.setCellSize(50)                 -- Santos's cell
exploration.setParameter("objective", "proportional")

for _, w in ipairs(Worlds) do
  local world = w.name
  exploration.setWorld(world)
  for _, m in ipairs(Methods) do
    exploration.setMethod(m.key)
    for seed = 0, SEEDS - 1 do
      exploration.setSeed(seed)
      robot.moveMobileSim(w.x, w.y, w.theta) -- else a run starts where the last one ended
      exploration.start()
      exploration.wait()
      local r = exploration.results()
      print(string.format("%s %s seed %d: %d visited cells, coverage %.3f, path %.1f m, %s", world, m.label,
                          seed, r.visited_cells, r.coverage, robot.pathLength() / 1000, r.reason))
      mapView.setMapScaling(0.05)           -- 50 px per metre
      robotView.setShowPath(true)
      mapView.saveMapImage(string.format("santos_%s_%s_s%d.png", world, m.label, seed))
    end
  end
end
