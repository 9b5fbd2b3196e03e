<!DOCTYPE qgis PUBLIC 'http://mrcc.com/qgis.dtd' 'SYSTEM'>
<qgis version="3.22.0-Białowieża" styleCategories="Symbology|Labeling" labelsEnabled="1">
  <renderer-v2 type="singleSymbol" symbollevels="0" enableorderby="0" forceraster="0" referencescale="-1">
    <symbols>
      <symbol type="fill" name="0" alpha="1" clip_to_extent="1" force_rhr="0">
        <layer class="SimpleFill" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="color" value="51,204,0,96" type="QString" />
            <Option name="style" value="solid" type="QString" />
            <Option name="outline_style" value="no" type="QString" />
          </Option>
          <prop k="color" v="51,204,0,96" />
          <prop k="style" v="solid" />
          <prop k="outline_style" v="no" />
        </layer>
        <layer class="SimpleLine" pass="0" locked="0" enabled="1">
          <Option type="Map">
            <Option name="line_color" value="51,204,0,255" type="QString" />
            <Option name="line_style" value="solid" type="QString" />
            <Option name="line_width" value="0.13" type="QString" />
            <Option name="line_width_unit" value="MM" type="QString" />
            <Option name="capstyle" value="flat" type="QString" />
            <Option name="joinstyle" value="round" type="QString" />
            <Option name="use_custom_dash" value="1" type="QString" />
            <Option name="customdash" value="2;1" type="QString" />
            <Option name="customdash_unit" value="MM" type="QString" />
          </Option>
          <prop k="line_color" v="51,204,0,255" />
          <prop k="line_style" v="solid" />
          <prop k="line_width" v="0.13" />
          <prop k="line_width_unit" v="MM" />
          <prop k="capstyle" v="flat" />
          <prop k="joinstyle" v="round" />
          <prop k="use_custom_dash" v="1" />
          <prop k="customdash" v="2;1" />
          <prop k="customdash_unit" v="MM" />
        </layer>
      </symbol>
    </symbols>
  </renderer-v2>
  <labeling type="simple">
    <settings calloutType="simple">
      <text-style fieldName="description" isExpression="0" fontFamily="Sans Serif" fontSize="8" fontSizeUnit="Point" textColor="0,0,0,255" textOpacity="1" namedStyle="Regular" multilineHeight="1" />
      <text-buffer bufferDraw="1" bufferSize="0.8" bufferSizeUnits="MM" bufferColor="255,255,255,255" bufferOpacity="1" />
      <placement placement="1" dist="1" distUnits="MM" centroidInside="1" />
      <rendering scaleVisibility="0" obstacle="1" displayAll="0" fontLimitPixelSize="0" />
    </settings>
  </labeling>
  <layerGeometryType>2</layerGeometryType>
</qgis>
