fout = io.open( [[resultados.txt]], "a+");

DensePoses = {
  [1] = {x = -5000, y = 7500, theta = 0 },
  [2] = {x = -1600, y = 7500, theta = 0 },
  [3] = {x = 2700, y = 7500, theta = 0 }
}

function results (name, n)
 elapsedTime = exploration.elapsedTime();
 path = robot.pathLength();
 fout:write( [[
 Map: ]] .. name .. [[ Pose: ]] .. n .. [[
 Elapse time: ]] .. elapsedTime .. [[
 Path length: ]] .. path .. [[
 ]]);
 fout:flush();
 mapView.setMapScaling(0.1);
 robotView.setShowPath(true);
 mapView.setShowGrid(true);
 mapView.saveMapImage( [[]] .. name .. [[_]] .. n .. [[.PNG]]);
end

robot.setAddress("localhost");
robot.setMaxLaserRange(3000);
exploration.setMethod(ExplorationMethod.BVP);

for num, pose in pairs(DensePoses) do
 fout:write("Starting BVP in pose " .. num .. "\n");
 fout:flush();
 robot.moveMobileSim(pose.x, pose.y, pose.theta);
 exploration.start();
 exploration.wait();
 results("Denso_PVC", num);
end
