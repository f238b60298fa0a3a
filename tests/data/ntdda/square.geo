<?xml version="1.0" standalone="no"?>
<!-- A unit square cut by its diagonal into two triangles: a DDAML geometry file as
     read by ntdda's ddaml_read_geometry_file (doolin/ntdda src/geomddaml.c); the layout
     follows doolin/ntdda examples/loadpoint/pushblock.geo. Joints overshoot the corners
     so that they cross. -->
<!DOCTYPE DDA SYSTEM "geometry.dtd">
<Berkeley:DDA xmlns:Berkeley="http://www.tsoft.com/~bdoolin/dda">
<Berkeley:Geometry>
   <Berkeley:Edgenodedist distance="0.01"/>
   <Jointlist>
      <Joint type="1"> -0.01 0 1.01 0 </Joint>
      <Joint type="1"> 1 -0.01 1 1.01 </Joint>
      <Joint type="1"> 1.01 1 -0.01 1 </Joint>
      <Joint type="1"> 0 1.01 0 -0.01 </Joint>
      <Joint type="2"> -0.01 -0.01 1.01 1.01 </Joint>
   </Jointlist>
   <Fixedpointlist>
      <Point> 0.9 0.1 </Point>
      <Line> 0.25 0.5 0.75 0.5 </Line>
   </Fixedpointlist>
   <Loadpointlist>
      <Point> 0.2 0.8 </Point>
   </Loadpointlist>
   <Measuredpointlist>
      <Point> 0.1 0.9 </Point>
      <Point> 0.7 0.2 </Point>
   </Measuredpointlist>
   <Boltlist>
      <Bolt> 0.8 0.3 0.3 0.8 </Bolt>
   </Boltlist>
   <Matlinelist>
      <Line type="2"> 0.1 0.6 0.2 0.7 </Line>
   </Matlinelist>
</Berkeley:Geometry>
</Berkeley:DDA>
